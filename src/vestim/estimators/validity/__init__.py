"""Validity flags: may a controller use this row's estimates? (issue 15)

Every output row gets, per group, ``valid_<group>`` (1 or 0) and ``reason_<group>``, a bit
mask of why not (0 when valid):

=====  ==================  ====================================================================
bit    reason              when
=====  ==================  ====================================================================
1      not converged       the first ``converge_s`` of the log (the filters start from a guess)
2      standstill          |v_x| < ``standstill_speed``: slips and slip angles are undefined
4      reverse             v_x < −``standstill_speed``: the filters are made for forward travel
8      high slip           a wheel beyond ``high_slip_ratio`` or ``high_slip_angle``: the
                           wheel-speed evidence of v_x and the linear-tire v_y are gone
16     unobservable        the per-corner lateral-force split with the wheels straight and no
                           lateral load (|δ| < ``straight_delta`` and |a_y| < ``straight_ay``):
                           the left/right shares then come from the model, not the data; or a
                           corner's normal load not resolved from zero (a wheel nearly lifted,
                           F_z below ``FZ_RESOLVED`` σ_Fz): its F/F_z is no friction use
32     input faulty        :meth:`~vestim.pipeline.Pipeline.step` held a dropped input value
64     v_y unverified      the reference filter has accepted no v_y pseudo-measurement for
                           ``unverified_s``: the tire model and the a_y integral disagree (a
                           slide, or an integral that drifted), and v_y is the integral alone
128    inconsistent        no wheel speed agrees with the estimate (:func:`consistency_step`):
                           every wheel's R ω differs from the estimate mapped to its corner
                           by more than ``consistent_speed`` + ``consistent_rel`` |v_x|,
                           low-passed over ``consistent_tau``: the estimate, not a wheel, is
                           wrong (a filter not re-converged after a gap, an IMU fault
                           integrated)
=====  ==================  ====================================================================

Groups and the reasons that apply to them: ``velocity`` (1, 2, 4, 8, 32, 64, 128),
``force`` (1, 2, 4, 16, 32), ``slip`` (1, 2, 4, 32, 64, 128). A bit that does not apply to a
group is never set in its mask.

Bit 128 is the test of the estimate itself (issue 30): the input tests (wheel and IMU health,
bit 32) see a faulty sensor, this one sees a wrong estimate whatever made it wrong. A car
has a wheel near free rolling unless all four slip at once (an AWD car braking or driving on
ice), so a correct estimate agrees with one of them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
from numba import njit

from vestim.params import check_ranges, pack

NOT_CONVERGED, STANDSTILL, REVERSE, HIGH_SLIP, UNOBSERVABLE, INPUT_FAULTY = 1, 2, 4, 8, 16, 32
VY_UNVERIFIED, INCONSISTENT = 64, 128
REASONS: dict[int, str] = {NOT_CONVERGED: "not converged", STANDSTILL: "standstill",
                           REVERSE: "reverse", HIGH_SLIP: "high slip",
                           UNOBSERVABLE: "unobservable", INPUT_FAULTY: "input faulty",
                           VY_UNVERIFIED: "v_y unverified", INCONSISTENT: "inconsistent"}
GROUPS: dict[str, int] = {
    "velocity": (NOT_CONVERGED | STANDSTILL | REVERSE | HIGH_SLIP | INPUT_FAULTY | VY_UNVERIFIED
                 | INCONSISTENT),
    "force": NOT_CONVERGED | STANDSTILL | REVERSE | UNOBSERVABLE | INPUT_FAULTY,
    "slip": NOT_CONVERGED | STANDSTILL | REVERSE | INPUT_FAULTY | VY_UNVERIFIED | INCONSISTENT,
}
"""The reason bits each group's mask can hold."""


@dataclass(frozen=True)
class ValidityParams:
    """Thresholds of the validity flags (SI; see the module docstring).

    The consistency test (bit 128): ``consistent_speed`` 0.2 m/s and ``consistent_rel``
    0.03: a free-rolling wheel's R ω is within a few cm/s of the CG speed mapped to its
    corner, a driven or braked wheel in its linear range within 1–2 % (slip), plus the wheel
    radius' error and the transport terms' (≈ 0.1 m/s); ``consistent_tau`` 0.1 s low-passes
    the wheel-speed noise (0.06 rad/s a sample) and an ABS cycle's dips. Measured with the
    default estimate on the 12 crossplant logs and the simulator's accel_brake and dlc_snow:
    the smallest residual reaches 0.39 of the tolerance (x10), so a correct estimate does not
    raise it there; a corner observer restarted on a spinning wheel (1.45 m/s off on the ice
    launch x02) is 5 times over it."""

    converge_s: float = 2.0
    standstill_speed: float = 0.5
    high_slip_ratio: float = 0.15
    high_slip_angle: float = 0.14
    straight_delta: float = 0.005
    straight_ay: float = 0.3
    unverified_s: float = 1.0
    consistent_speed: float = 0.2
    consistent_rel: float = 0.03
    consistent_tau: float = 0.1

    def __post_init__(self) -> None:
        check_ranges(self, "validity", nonnegative=(f.name for f in fields(self)))


def output_names() -> list[str]:
    """``valid_<group>``, ``reason_<group>`` per group, in :data:`GROUPS` order."""
    return [n for g in GROUPS for n in (f"valid_{g}", f"reason_{g}")]


class ValidityKernelParams(NamedTuple):
    """:func:`validity_step`'s parameters: the :class:`ValidityParams` fields (SI)."""

    converge_s: float
    standstill_speed: float
    high_slip_ratio: float
    high_slip_angle: float
    straight_delta: float
    straight_ay: float
    unverified_s: float
    consistent_speed: float
    consistent_rel: float
    consistent_tau: float


class ConsistencyState(NamedTuple):
    """:func:`consistency_step`'s state: ``e`` (4,) the low-passed residuals R ω − v̂_xt per
    corner (fl, fr, rl, rr), m/s (NaN: not started), ``t_prev`` (1,) the previous sample's
    time, s (NaN: none)."""

    e: np.ndarray
    t_prev: np.ndarray


def new_consistency_state() -> ConsistencyState:
    """A fresh :class:`ConsistencyState` (nothing seen)."""
    return ConsistencyState(np.full(4, np.nan), np.full(1, np.nan))


@njit(cache=True, error_model="numpy", inline="always")
def consistency_step(p: ValidityKernelParams, s: ConsistencyState, t: float, radius: float,
                     vx: float, omega: np.ndarray, vxt: np.ndarray) -> float:
    """The test of the estimate itself (bit 128) for one sample at ``t`` (s): does a wheel's
    speed R ω (``radius`` m; ``omega`` (4,) rad/s, the calibrated radius' scale included)
    agree with the estimate mapped to its corner, ``vxt`` (4,) m/s (tire frame)?

    Each residual R ω − v̂_xt is low-passed over ``consistent_tau`` (started afresh after a
    time step over ``converge_s`` or a clock jump); the smallest magnitude is held against
    ``consistent_speed`` + ``consistent_rel`` |``vx``| (m/s). Returns 1.0 (consistent), 0.0
    (no wheel agrees) or NaN (no wheel speed to test with). ``s`` is advanced."""
    dt = t - s.t_prev[0]
    a = dt / (p.consistent_tau + dt) if 0.0 < dt <= p.converge_s else 1.0
    s.t_prev[0] = t
    best = np.inf
    for c in range(4):
        e = radius * omega[c] - vxt[c]
        if np.isnan(e):
            continue
        s.e[c] = e if (np.isnan(s.e[c]) or a == 1.0) else s.e[c] + a * (e - s.e[c])
        best = min(best, abs(s.e[c]))
    if best == np.inf:
        return np.nan
    return 1.0 if best <= p.consistent_speed + p.consistent_rel * abs(vx) else 0.0


def validity_params(p: ValidityParams) -> ValidityKernelParams:
    """:func:`validity_step`'s parameters from the validated ``p``."""
    return pack(ValidityKernelParams, p)


FZ_RESOLVED = 2.0
"""A corner's F_z below this many of its σ_Fz is not resolved from zero (a wheel nearly
lifted): its μ_x = F_x/F_z and μ_y = F_y/F_z say nothing of the friction used there, so the
output writes them 0 (the lifted wheel's convention) and the row's force group is not valid,
reason 16. Campaign s1_014's rear right carried 302 N where the estimate read 2 N: F_x/F_z
was 41.7."""


@njit(cache=True, error_model="numpy", inline="always")
def load_resolved(fz: float, sigma_fz: float) -> bool:
    """Whether a corner's normal load ``fz`` (N) is resolved from zero by its one-sigma
    ``sigma_fz`` (N): F_z ≥ :data:`FZ_RESOLVED` σ_Fz (NaN σ: resolved)."""
    return not fz < FZ_RESOLVED * sigma_fz


MASKS = np.array(list(GROUPS.values()), dtype=np.int64)
"""The groups' reason masks, in :data:`GROUPS` order (a compile-time constant of
:func:`validity_step`)."""


@njit(cache=True, error_model="numpy", inline="always")
def validity_step(p: ValidityKernelParams, t: float, t_start: float, vx: float,
                  slip_ratio: np.ndarray, slip_angle: np.ndarray, delta_l: float,
                  delta_r: float, ay: float, vy_unverified: float, held: bool,
                  consistent: float, load_unresolved: bool, valid: np.ndarray,
                  reason: np.ndarray) -> None:
    """The flags of the module docstring for one sample at time ``t`` (s; ``t_start`` the
    log's first, s): CG ``vx`` (m/s), per-corner ``slip_ratio`` and ``slip_angle`` (4,)
    (NaN: not known, no flag), the front road-wheel angles ``delta_l``, ``delta_r`` (rad),
    ``ay`` (m/s²), ``vy_unverified`` (s since the reference filter last accepted a v_y
    pseudo-measurement; NaN: no such filter, no flag), ``held`` (an input value was held
    over a dropout), ``consistent`` (:func:`consistency_step`'s: 0.0 sets bit 128, 1.0 or
    NaN does not) and ``load_unresolved`` (a corner's F_z below :data:`FZ_RESOLVED` σ_Fz:
    bit 16, see :func:`load_resolved`). ``valid`` and
    ``reason`` (groups,) are written, one entry per :data:`GROUPS` group (stateless)."""
    bits = 0
    if t - t_start < p.converge_s:
        bits |= NOT_CONVERGED
    if abs(vx) < p.standstill_speed:
        bits |= STANDSTILL
    if vx <= -p.standstill_speed:
        bits |= REVERSE
    for c in range(4):  # NaN (not known) compares False: no flag
        if abs(slip_ratio[c]) > p.high_slip_ratio or abs(slip_angle[c]) > p.high_slip_angle:
            bits |= HIGH_SLIP
    if ((max(abs(delta_l), abs(delta_r)) < p.straight_delta and abs(ay) < p.straight_ay)
            or load_unresolved):
        bits |= UNOBSERVABLE
    if held:
        bits |= INPUT_FAULTY
    if vy_unverified >= p.unverified_s:
        bits |= VY_UNVERIFIED
    if consistent == 0.0:
        bits |= INCONSISTENT
    for g in range(MASKS.shape[0]):
        m = bits & MASKS[g]
        valid[g] = 1.0 if m == 0 else 0.0
        reason[g] = float(m)


@njit(cache=True, error_model="numpy")
def validity_kernel(p: ValidityKernelParams, t: np.ndarray, t_start: float, vx: np.ndarray,
                    slip_ratio: np.ndarray, slip_angle: np.ndarray, delta: np.ndarray,
                    ay: np.ndarray, vy_unverified: np.ndarray, held: np.ndarray,
                    consistent: np.ndarray, load_unresolved: np.ndarray, valid: np.ndarray,
                    reason: np.ndarray) -> None:
    """:func:`validity_step` over a block of samples (see :func:`validity`); ``valid``,
    ``reason`` (n, groups) are written, one column per :data:`GROUPS` entry."""
    for k in range(t.shape[0]):
        validity_step(p, t[k], t_start, vx[k], slip_ratio[k], slip_angle[k], delta[k, 0],
                      delta[k, 1], ay[k], vy_unverified[k], held[k], consistent[k],
                      load_unresolved[k], valid[k], reason[k])


def validity(t: np.ndarray, t_start: float, vx: np.ndarray, slip_ratio: np.ndarray,
             slip_angle: np.ndarray, delta: np.ndarray, ay: np.ndarray, input_held: np.ndarray,
             p: ValidityParams, vy_unverified: np.ndarray | None = None,
             consistent: np.ndarray | None = None,
             load_unresolved: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The flags of the module docstring for a block of samples.

    Args:
        t: sample times (n,), s; t_start: the log's (or live feed's) first time, s.
        vx: CG v_x (n,), m/s. slip_ratio, slip_angle: (n, 4), – and rad (NaN: not known,
            e.g. no wheel speeds; it raises no flag). delta: front road-wheel angles (n, 2),
            rad. ay: lateral specific force (n,), m/s². input_held: (n,) True where an input
            value was held over a dropout.
        vy_unverified: (n,) s since the reference filter last accepted a v_y
            pseudo-measurement (None or NaN: no such filter, no flag).
        consistent: (n,) :func:`consistency_step`'s results, 1.0, 0.0 (bit 128) or NaN
            (None: not tested, no flag).
        load_unresolved: (n,) True where a corner's F_z is not resolved from zero
            (:func:`load_resolved`; None: no flag).

    Returns:
        ``valid_<group>`` (1.0/0.0) and ``reason_<group>`` (the bit mask as a float), (n,).
    """
    n = t.shape[0]
    valid, reason = np.empty((n, len(GROUPS))), np.empty((n, len(GROUPS)))
    c = np.ascontiguousarray
    unverified = np.full(n, np.nan) if vy_unverified is None else vy_unverified
    tested = np.full(n, np.nan) if consistent is None else consistent
    lifted = np.zeros(n, np.bool_) if load_unresolved is None else load_unresolved
    validity_kernel(validity_params(p), c(t, dtype=np.float64), float(t_start),
                    c(vx, dtype=np.float64), c(slip_ratio, dtype=np.float64),
                    c(slip_angle, dtype=np.float64), c(delta, dtype=np.float64),
                    c(ay, dtype=np.float64), c(unverified, dtype=np.float64),
                    c(input_held, dtype=np.bool_), c(tested, dtype=np.float64),
                    c(lifted, dtype=np.bool_), valid, reason)
    out: dict[str, np.ndarray] = {}
    for j, group in enumerate(GROUPS):
        out[f"valid_{group}"] = valid[:, j]
        out[f"reason_{group}"] = reason[:, j]
    return out


def reason_names(mask: float) -> list[str]:
    """The reasons of a ``reason_<group>`` bit mask, lowest bit first (:data:`REASONS`):
    ``reason_names(3)`` → ``["not converged", "standstill"]``; ``[]`` for 0 (valid).

    Raises:
        ValueError: ``mask`` is negative, not a whole number, or holds a bit no reason has.
    """
    value = float(mask)
    if not (value >= 0 and value == int(value)):
        raise ValueError(f"reason mask {mask!r} is not a non-negative whole number")
    bits = int(value)
    unknown = bits & ~sum(REASONS)
    if unknown:
        raise ValueError(f"reason mask {bits} holds bit(s) {unknown} that no reason has; "
                         f"known bits: {', '.join(f'{b} {n}' for b, n in REASONS.items())}")
    return [name for bit, name in REASONS.items() if bits & bit]
