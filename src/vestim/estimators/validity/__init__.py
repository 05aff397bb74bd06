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
                           the left/right shares then come from the model, not the data
32     input faulty        :meth:`~vestim.pipeline.Pipeline.step` held a dropped input value
=====  ==================  ====================================================================

Groups and the reasons that apply to them: ``velocity`` (1, 2, 4, 8, 32), ``force``
(1, 2, 4, 16, 32), ``slip`` (1, 2, 4, 32). A bit that does not apply to a group is never set
in its mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NOT_CONVERGED, STANDSTILL, REVERSE, HIGH_SLIP, UNOBSERVABLE, INPUT_FAULTY = 1, 2, 4, 8, 16, 32
REASONS: dict[int, str] = {NOT_CONVERGED: "not converged", STANDSTILL: "standstill",
                           REVERSE: "reverse", HIGH_SLIP: "high slip",
                           UNOBSERVABLE: "unobservable", INPUT_FAULTY: "input faulty"}
GROUPS: dict[str, int] = {
    "velocity": NOT_CONVERGED | STANDSTILL | REVERSE | HIGH_SLIP | INPUT_FAULTY,
    "force": NOT_CONVERGED | STANDSTILL | REVERSE | UNOBSERVABLE | INPUT_FAULTY,
    "slip": NOT_CONVERGED | STANDSTILL | REVERSE | INPUT_FAULTY,
}
"""The reason bits each group's mask can hold."""


@dataclass(frozen=True)
class ValidityParams:
    """Thresholds of the validity flags (SI; see the module docstring)."""

    converge_s: float = 2.0
    standstill_speed: float = 0.5
    high_slip_ratio: float = 0.15
    high_slip_angle: float = 0.14
    straight_delta: float = 0.005
    straight_ay: float = 0.3

    def __post_init__(self) -> None:
        for name in ("converge_s", "standstill_speed", "high_slip_ratio", "high_slip_angle",
                     "straight_delta", "straight_ay"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"validity {name} = {getattr(self, name)} must be >= 0")


def output_names() -> list[str]:
    """``valid_<group>``, ``reason_<group>`` per group, in :data:`GROUPS` order."""
    return [n for g in GROUPS for n in (f"valid_{g}", f"reason_{g}")]


def validity(t: np.ndarray, t_start: float, vx: np.ndarray, slip_ratio: np.ndarray,
             slip_angle: np.ndarray, delta: np.ndarray, ay: np.ndarray, input_held: np.ndarray,
             p: ValidityParams) -> dict[str, np.ndarray]:
    """The flags of the module docstring for a block of samples.

    Args:
        t: sample times (n,), s; t_start: the log's (or live feed's) first time, s.
        vx: CG v_x (n,), m/s. slip_ratio, slip_angle: (n, 4), – and rad (NaN: not known,
            e.g. no wheel speeds; it raises no flag). delta: front road-wheel angles (n, 2),
            rad. ay: lateral specific force (n,), m/s². input_held: (n,) True where an input
            value was held over a dropout.

    Returns:
        ``valid_<group>`` (1.0/0.0) and ``reason_<group>`` (the bit mask as a float), (n,).
    """
    bits = np.zeros(t.shape[0], dtype=np.int64)
    bits |= np.where(t - t_start < p.converge_s, NOT_CONVERGED, 0)
    bits |= np.where(np.abs(vx) < p.standstill_speed, STANDSTILL, 0)
    bits |= np.where(vx <= -p.standstill_speed, REVERSE, 0)
    with np.errstate(invalid="ignore"):
        slipping = (np.nanmax(np.abs(np.nan_to_num(slip_ratio, nan=0.0)), axis=1) > p.high_slip_ratio) | (
            np.nanmax(np.abs(np.nan_to_num(slip_angle, nan=0.0)), axis=1) > p.high_slip_angle)
    bits |= np.where(slipping, HIGH_SLIP, 0)
    straight = (np.max(np.abs(delta), axis=1) < p.straight_delta) & (np.abs(ay) < p.straight_ay)
    bits |= np.where(straight, UNOBSERVABLE, 0)
    bits |= np.where(input_held, INPUT_FAULTY, 0)
    out: dict[str, np.ndarray] = {}
    for group, allowed in GROUPS.items():
        mask = bits & allowed
        out[f"valid_{group}"] = (mask == 0).astype(np.float64)
        out[f"reason_{group}"] = mask.astype(np.float64)
    return out
