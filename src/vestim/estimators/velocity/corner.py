"""Per-corner, tire-model-based velocity observers (issue 4): LuGre Kalman, LuGre UKF, LPV.

Each corner's longitudinal wheel-centre speed in its tire frame, v_xt, is
estimated from that corner's wheel speed, normalised longitudinal force μ_x
(force stage) and kinematic acceleration, through the average lumped LuGre
model with the road-friction term treated as a bounded disturbance — no road
friction coefficient is needed (000 Sec. III, 001 Sec. IV, 003 Sec. II, 004 Sec. III).

Methods (``method=``):

* ``"lugre_kf"`` — time-varying Kalman filter on [z̄_x, v_rx, ż̄_x], 000 eq. (16)–(23),
  step-invariant discretisation, high-slip module with the adaptive threshold of
  000 eq. (29) and the |ω̇| criterion switching Q̄, R̄ (:mod:`.lugre_kf`, :mod:`.corner_slip`);
* ``"lugre_ukf"`` — the same model and switching with the UKF of 003 Algorithm 1;
* ``"lpv"`` — LPV observers: longitudinal 001 eq. (24) or 004 eq. (10)–(14) (constant
  or eq. (35) scheduled gains), lateral 001 eq. (38) (:mod:`.lpv_observer`;
  :class:`LPVParams` presets ``paper_001()`` (default), ``paper_004()``,
  ``paper_004_scheduled()``, or any :class:`GainSchedule`).

Inputs (:class:`CornerVelocityInput`), corner order fl, fr, rl, rr:

* ``t`` (n,) s, strictly increasing (also across successive ``advance`` calls);
* ``omega`` (n, 4) rad/s, measured wheel speeds;
* ``mu_x``, ``mu_y`` (n, 4): normalised tire forces F/F_z of the force stage (tire frame);
* ``a_xt``, ``a_yt`` (n, 4) m/s²: kinematic (inertial) acceleration of each wheel centre
  projected on its tire axes — the IMU specific force rotated to the road plane by
  the body angles, transported to the corner; grade and bank stay in it as a slowly
  varying bias (:func:`~.corner_inputs.corner_inputs` builds them from a log);
* ``delta`` (n, 4) rad road-wheel angles (rear 0); ``yaw_rate`` (n,) rad/s;
* optional ``high_slip_hint`` (n, 4) bool (OR-ed into the high-slip flags) and
  ``vyt`` (n, 4) m/s (tire-frame lateral speeds for the transport term
  v̇_xt = a_xt + (r + δ̇) v_yt; NaN or absent: the lateral LPV's own estimate, or
  the no-side-slip approximation of :func:`~.corner_common.vyt_no_sideslip`).

Outputs (:class:`CornerVelocityOutput`), each (n, 4): ``vxt`` = Rω − v̂_rx (000 Sec. III-B),
``vyt`` = −v̂_ry (lateral LPV, else NaN), ``sigma_vxt`` = √P_vr (Kalman methods, else
NaN; the wheel-speed noise that cancels in Rω − v̂_rx is not in it), ``sigma_vyt``
(NaN: no method has one), ``high_slip`` flags, and the LuGre states.

``advance`` over a whole log and sample-by-sample ``advance`` run the same compiled
kernel on the same state and give bit-identical results. Nothing here reads
``ref_`` channels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from numba import njit

from vestim.constants import CORNERS
from vestim.estimators.registry import register, registered
from vestim.estimators.velocity.corner_common import (
    CornerInputs,
    CornerOutputs,
    CornerParams,
    CornerState,
    new_hold,
)
from vestim.estimators.velocity.corner_slip import HighSlipParams
from vestim.estimators.velocity.lpv_observer import (
    GAINS_001_X,
    GAINS_001_Y,
    GAINS_004,
    GAINS_004_SCHEDULED,
    GainSchedule,
    LPVParams,
    gains_004_eq35,
    lpv_kernel,
)
from vestim.estimators.velocity.lpv_observer import VRS as LPV_VR
from vestim.estimators.velocity.lugre_kf import VR as KF_VR
from vestim.estimators.velocity.lugre_kf import KFParams, lugre_kf_kernel
from vestim.filters.ukf import ukf_weights
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import corner_positions

__all__ = [
    "GAINS_001_X",
    "GAINS_001_Y",
    "GAINS_004",
    "GAINS_004_SCHEDULED",
    "LPV",
    "LUGRE_KF",
    "LUGRE_UKF",
    "METHODS",
    "CornerVelocityEstimator",
    "CornerVelocityInput",
    "CornerVelocityOutput",
    "GainSchedule",
    "HighSlipParams",
    "KFParams",
    "LPVParams",
    "gains_004_eq35",
]

register("corner", "lugre_kf", "LuGre corner Kalman filter on [z̄_x, v_rx, ż̄_x] with the "
         "high-slip switch", cite="000 eq. (16)–(23), (29)", default=True,
         params=KFParams)(lugre_kf_kernel)
register("corner", "lugre_ukf", "the LuGre corner model and switching with the UKF",
         cite="003 Alg. 1", params=KFParams)(lugre_kf_kernel)
register("corner", "lpv", "LPV corner observers, longitudinal and lateral",
         cite="001 eq. (24), (38); 004 eq. (10)–(14), (35)", params=LPVParams)(lpv_kernel)
_REGISTERED = registered("corner")
METHODS: tuple[str, ...] = tuple(_REGISTERED)
"""The corner observers' names, in the registry's order (each registered with its kernel and
its Params class)."""
LUGRE_KF, LUGRE_UKF, LPV = (_REGISTERED[name].code for name in ("lugre_kf", "lugre_ukf", "lpv"))
"""The corner observers' registry codes."""


def _corner_array(name: str, value: object, n: int, dtype: type = np.float64) -> np.ndarray:
    arr: np.ndarray = np.ascontiguousarray(value, dtype=dtype)
    if arr.shape != (n, 4):
        raise ValueError(f"CornerVelocityInput.{name} has shape {arr.shape}; expected ({n}, 4) "
                         "(samples × corners fl, fr, rl, rr)")
    return arr


def _absent() -> np.ndarray:
    """Default of an optional input: an empty array, replaced on construction (NaN / False)."""
    return np.empty((0, 4))


def _is_absent(value: object) -> bool:
    return value is None or (isinstance(value, np.ndarray) and value.size == 0)


@dataclass(frozen=True)
class CornerVelocityInput:
    """Per-corner inputs of a chunk of n samples (see the module docstring for units and meaning).

    Arrays are converted to contiguous float64 (bool for the hint) on construction;
    the caller's arrays are never modified. Optional inputs left out (or given as
    None) become NaN arrays (``mu_y``, ``a_yt``, ``vyt``) or False (``high_slip_hint``).
    """

    t: np.ndarray
    omega: np.ndarray
    mu_x: np.ndarray
    a_xt: np.ndarray
    delta: np.ndarray
    yaw_rate: np.ndarray
    mu_y: np.ndarray = field(default_factory=_absent)
    a_yt: np.ndarray = field(default_factory=_absent)
    high_slip_hint: np.ndarray = field(default_factory=_absent)
    vyt: np.ndarray = field(default_factory=_absent)

    def __post_init__(self) -> None:
        t = np.ascontiguousarray(self.t, dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"CornerVelocityInput.t must be 1-D (n,), got shape {t.shape}")
        n = t.shape[0]
        finite = t[np.isfinite(t)]
        if np.any(np.diff(finite) <= 0):
            raise ValueError("CornerVelocityInput.t must be strictly increasing")
        object.__setattr__(self, "t", t)
        for name in ("omega", "mu_x", "a_xt", "delta"):
            object.__setattr__(self, name, _corner_array(name, getattr(self, name), n))
        r = np.ascontiguousarray(self.yaw_rate, dtype=np.float64)
        if r.shape != (n,):
            raise ValueError(f"CornerVelocityInput.yaw_rate has shape {r.shape}; expected ({n},)")
        object.__setattr__(self, "yaw_rate", r)
        for name in ("mu_y", "a_yt", "vyt"):
            v = getattr(self, name)
            object.__setattr__(self, name, np.full((n, 4), np.nan) if _is_absent(v)
                               else _corner_array(name, v, n))
        hint = self.high_slip_hint
        object.__setattr__(self, "high_slip_hint", np.zeros((n, 4), dtype=np.bool_)
                           if _is_absent(hint) else _corner_array("high_slip_hint", hint, n, np.bool_))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def slice(self, start: int, stop: int) -> CornerVelocityInput:
        """Samples [start, stop) as a new input (for chunked or per-sample processing)."""
        kw = {f.name: getattr(self, f.name)[start:stop] for f in fields(self)}
        return CornerVelocityInput(**kw)


@dataclass(frozen=True)
class CornerVelocityOutput:
    """Estimates of a chunk, each (n, 4) in corner order fl, fr, rl, rr.

    Attributes:
        vxt: tire-frame longitudinal wheel-centre speed v̂_xt = Rω − v̂_rx, m/s.
        vyt: tire-frame lateral speed −v̂_ry (lateral LPV), else NaN, m/s.
        sigma_vxt: one-sigma of v̂_xt from the filter covariance (Kalman methods), else NaN.
        sigma_vyt: NaN (no method carries a lateral covariance).
        high_slip: high-slip flags (they switch Q̄, R̄ in the Kalman methods; LPV reports them).
        v_rx, z_x, zdot_x: longitudinal relative velocity (m/s), deflection (m), its rate (m/s;
            Kalman methods, else NaN).
        v_ry, z_y: lateral relative velocity and deflection (lateral LPV, else NaN).
    """

    vxt: np.ndarray
    vyt: np.ndarray
    sigma_vxt: np.ndarray
    sigma_vyt: np.ndarray
    high_slip: np.ndarray
    v_rx: np.ndarray
    z_x: np.ndarray
    zdot_x: np.ndarray
    v_ry: np.ndarray
    z_y: np.ndarray

    def columns(self) -> dict[str, np.ndarray]:
        """The estimates under the spec's channel names (``vxt_fl`` …, ``sigma_vxt_fl`` …,
        ``high_slip_fl`` …); all-NaN quantities are left out."""
        out: dict[str, np.ndarray] = {}
        for name in ("vxt", "vyt", "sigma_vxt", "sigma_vyt", "high_slip"):
            arr = getattr(self, name)
            if arr.dtype != np.bool_ and np.all(np.isnan(arr)):
                continue
            for i, c in enumerate(CORNERS):
                out[f"{name}_{c}"] = arr[:, i]
        return out


def corner_params(vehicle: Vehicle, method: str,
                  params: KFParams | LPVParams) -> CornerParams:
    """The kernels' parameter tree of a corner observer (``method`` one of :data:`METHODS`,
    ``params`` of its kind): the vehicle's [tire] and geometry, the method's own values, and
    placeholders for the other method's fields."""
    code = _REGISTERED[method].code
    tire = vehicle.tire
    hs = params.high_slip
    z1 = np.zeros(1)
    wm, wc, tau = ukf_weights(3)
    if isinstance(params, KFParams):
        kf = (float(params.r), float(params.r_high), float(params.step_ref))
        kf_arrays = (np.array(params.q), np.array(params.q_high), np.array(params.p0))
        gx = gy = (z1, z1, z1)
        lateral = False
    else:
        kf, kf_arrays = (0.0, 0.0, 0.0), (z1, z1, z1)
        gx = params.longitudinal.innovation_gains(tire.sigma1_x)
        # placeholder arrays when the lateral observer is off
        gy = (params.lateral or GAINS_001_Y).innovation_gains(tire.sigma1_y)
        lateral = params.lateral is not None
    return CornerParams(
        code == LPV, float(vehicle.body.wheel_radius),
        np.ascontiguousarray(corner_positions(vehicle)[0]), tire.kappa_x, tire.sigma0_x,
        tire.sigma1_x, tire.sigma2_x, *kf, hs.lambda_upper, hs.lambda_lower, hs.beta_e,
        hs.omega_dot_threshold, hs.min_speed, hs.mu_release, *kf_arrays,
        int(hs.release_window), code == LUGRE_UKF, wm, wc, float(tau), tire.kappa_y,
        tire.sigma0_y, tire.sigma1_y, tire.sigma2_y, *gx, lateral, *gy)


@njit(cache=True, error_model="numpy")
def corner_rows(p: CornerParams, s: CornerState, inp: CornerInputs, out: CornerOutputs) -> None:
    """The corner observer ``p`` names (LPV, else the LuGre KF/UKF) over a chunk, in place on
    ``s`` and ``out``."""
    if p.lpv:
        lpv_kernel(p, s, inp, out)
    else:
        lugre_kf_kernel(p, s, inp, out)


@njit(cache=True, error_model="numpy")
def seed_corners(p: CornerParams, s: CornerState, omega: np.ndarray, vxt: np.ndarray) -> None:
    """Re-initialise the observers' relative velocity v_r = R ω − v_xt from an outside
    estimate of the corners' tire-frame speeds ``vxt`` (4,) m/s at the wheel speeds ``omega``
    (4,) rad/s of the sample last processed (the pipeline's reference filter after a restart,
    :data:`vestim.pipeline.rows.SEED_AT`); a corner with a NaN in either is left as it is.
    The deflection and the covariance are kept: they follow the force, not the speed."""
    for c in range(4):
        v_r = p.radius * omega[c] - vxt[c]
        if np.isnan(v_r):
            continue
        if p.lpv:
            s.xx[c, LPV_VR] = v_r
        else:
            s.x[c, KF_VR] = v_r


class CornerVelocityEstimator:
    """Tire-model-based corner velocity observer, four corners, online or batch.

    Args:
        vehicle: uses ``[tire]`` (σ0, σ1, σ2, κ per direction) and ``[vehicle]``
            wheel_radius, lf, lr (corner positions for the transport term).
        method: one of :data:`METHODS`.
        params: :class:`KFParams` for ``lugre_kf``/``lugre_ukf``, :class:`LPVParams` for
            ``lpv``; None takes the papers' values.

    Raises:
        ValueError: unknown method, or params of the wrong kind for it.
    """

    def __init__(self, vehicle: Vehicle, method: str = "lugre_kf",
                 params: KFParams | LPVParams | None = None) -> None:
        if method not in METHODS:
            raise ValueError(f"corner velocity method {method!r}: use one of {', '.join(METHODS)}")
        kind = _REGISTERED[method].params
        assert kind is not None  # every corner observer registers its Params class above
        chosen: object = kind() if params is None else params
        if not isinstance(chosen, kind) or not isinstance(chosen, KFParams | LPVParams):
            raise ValueError(f"method {method!r} takes {kind.__name__}, "
                             f"got {type(chosen).__name__}")
        self.vehicle = vehicle
        self.method = method
        self.code = _REGISTERED[method].code
        """The observer's registry code (:data:`LUGRE_KF`, :data:`LUGRE_UKF`, :data:`LPV`)."""
        self.params: KFParams | LPVParams = chosen
        self.kernel_params = corner_params(vehicle, method, chosen)
        """The kernels' parameter tree (:class:`~.corner_common.CornerParams`)."""
        self.reset()

    @property
    def covariance(self) -> np.ndarray:
        """Copy of the Kalman methods' current covariance P (4, 3, 3) over [z̄_x, v_rx, ż̄_x];
        zeros for ``lpv`` and before the first sample."""
        return self.state.P.copy()

    @property
    def _slip(self) -> HighSlipParams:
        return self.params.high_slip

    def reset(self) -> None:
        """Forget all states; the next sample initialises them (free rolling, v_r = 0)."""
        hs = self._slip
        self.state = CornerState(
            x=np.zeros((4, 3)), P=np.zeros((4, 3, 3)), xx=np.zeros((4, 2)),
            xy=np.zeros((4, 2)), hold=new_hold(), acc=np.zeros(hs.accel_window),
            stats=np.zeros(3), w_buf=np.zeros((hs.omega_dot_window, 4)),
            t_buf=np.zeros(hs.omega_dot_window), ring=np.zeros(3, dtype=np.int64))
        self._t_last = -math.inf

    def advance(self, inp: CornerVelocityInput) -> CornerVelocityOutput:
        """Process a chunk of samples, continuing from the state left by the previous call."""
        n = len(inp)
        finite = inp.t[np.isfinite(inp.t)]
        if finite.size and finite[0] <= self._t_last:
            raise ValueError(f"CornerVelocityInput.t starts at {finite[0]} s, not after the last "
                             f"sample already processed ({self._t_last} s); call reset() first")
        if (self.code == LPV and self.kernel_params.lateral
                and np.all(np.isnan(inp.mu_y))):
            raise ValueError("the lateral LPV observer needs mu_y (and a_yt); give them in "
                             "CornerVelocityInput or use LPVParams(lateral=None)")
        nan4 = np.full((n, 4), np.nan)
        out = CornerOutputs(vxt=nan4.copy(), vyt=nan4.copy(), sigma=nan4.copy(),
                            high=np.zeros((n, 4), dtype=np.bool_), vrx=nan4.copy(),
                            zx=nan4.copy(), zdot=nan4.copy(), vry=nan4.copy(), zy=nan4.copy())
        corner_rows(self.kernel_params, self.state,
                    CornerInputs(inp.t, inp.omega, inp.mu_x, inp.mu_y, inp.a_xt, inp.a_yt,
                                 inp.delta, inp.yaw_rate, inp.high_slip_hint, inp.vyt), out)
        result = CornerVelocityOutput(out.vxt, out.vyt, out.sigma, nan4, out.high, out.vrx,
                                      out.zx, out.zdot, out.vry, out.zy)
        if finite.size:
            self._t_last = float(finite[-1])
        return result

    def run(self, inp: CornerVelocityInput) -> CornerVelocityOutput:
        """Reset, then process ``inp`` as one chunk."""
        self.reset()
        return self.advance(inp)
