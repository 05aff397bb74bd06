"""Frozen, validated settings of the stiffness estimators: the stiffness prior and the filter tuning.

Values are SI. :class:`StiffnessPrior` holds the nominal axle-total stiffness
C_n of 002 eq. (7), its initial one-sigma and the projection bounds of 002
Sec. V; :class:`StiffnessConfig` holds the sensor noise (R, Q of eq. (11)–(12)),
the NiW initialisation and forgetting (eq. (19)–(20)), resampling, activation
thresholds and the input pre-filter. Both reject unknown keywords (dataclass
constructors) and non-physical values with a ``ValueError`` that names the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from vestim.constants import G
from vestim.io.vehicle import Vehicle

Quad = tuple[float, float, float, float]

GENERIC_CX_PER_LOAD: tuple[float, float, float] = (3.0, 20.0, 100.0)
"""Generic longitudinal slip stiffness per unit normal load (lower, nominal, upper), 1/unit slip.

Passenger-car tires give C^x/F_z ≈ 10–30 on dry asphalt and roughly a third of
that on ice and snow; the range is widened to 3–100 so that the LuGre tire of
the vehicle files (σ0/κ ≈ 76) stays inside the projection bounds."""

GENERIC_CY_PER_LOAD: tuple[float, float, float] = (2.0, 10.0, 40.0)
"""Generic cornering stiffness per unit normal load (lower, nominal, upper), 1/rad.

Dry asphalt gives C^y/F_z ≈ 10–20 /rad (stiff sport tires near 25–30), snow and ice
3–6 /rad. The upper bound is a physical limit, not the expected range: the projection
of 002 Sec. V clips each draw of w, and a bound within a few per-step sigmas of the
truth truncates the draws and biases the estimate towards the inside (25 /rad held the
cross-plant PAC2002 tire's 21.9 /rad 12 % low; docs/methods_stiffness.md)."""

GENERIC_REL_SIGMA = 0.5
"""Initial one-sigma of the generic prior relative to its nominal value (ice and dry
asphalt are both within about 2 sigma of the nominal)."""

TABLE_REL_SIGMA = 0.3
"""Initial one-sigma relative to a vehicle file's ``[stiffness]`` table (002 Sec. VI-A: 30 %)."""

TABLE_BOUNDS = (0.1, 3.0)
"""Projection bounds relative to a ``[stiffness]`` table (ice to well above dry)."""


def _check_quad(name: str, values: Quad, positive: bool = True) -> None:
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"StiffnessPrior.{name} = {values} must be four finite values "
                         "(cx_f, cx_r, cy_f, cy_r)")
    if positive and not all(v > 0 for v in values):
        raise ValueError(f"StiffnessPrior.{name} = {values} must be positive")


@dataclass(frozen=True)
class StiffnessPrior:
    """Nominal axle-total stiffness, its initial uncertainty and physical bounds.

    Every field is (cx_f, cx_r, cy_f, cy_r): cx in N per unit slip ratio, cy in N/rad.

    Attributes:
        nominal: C_n of 002 eq. (7); the filters estimate the deviation ΔC from it.
        sigma: initial one-sigma of the stiffness (particle spread of μ̂_0 and √Σ_0).
        lower, upper: projection bounds (002 Sec. V); ``lower < nominal < upper``.
    """

    nominal: Quad
    sigma: Quad
    lower: Quad
    upper: Quad

    def __post_init__(self) -> None:
        for name in ("nominal", "sigma", "lower", "upper"):
            _check_quad(name, getattr(self, name))
        for i, (lo, c, hi) in enumerate(zip(self.lower, self.nominal, self.upper, strict=True)):
            if not lo < c < hi:
                raise ValueError(f"StiffnessPrior: component {i} needs lower < nominal < upper, "
                                 f"got {lo} < {c} < {hi}")

    @classmethod
    def from_table(cls, nominal: Quad, rel_sigma: float = TABLE_REL_SIGMA,
                   bounds: tuple[float, float] = TABLE_BOUNDS) -> StiffnessPrior:
        """Prior around known nominal values with a relative sigma and relative bounds."""
        return cls(nominal=tuple(nominal),  # type: ignore[arg-type]
                   sigma=tuple(rel_sigma * c for c in nominal),  # type: ignore[arg-type]
                   lower=tuple(bounds[0] * c for c in nominal),  # type: ignore[arg-type]
                   upper=tuple(bounds[1] * c for c in nominal))  # type: ignore[arg-type]

    @classmethod
    def generic(cls, vehicle: Vehicle) -> StiffnessPrior:
        """Generic prior from the static axle loads F_z,f = m g l_r/L, F_z,r = m g l_f/L.

        C^x = 20·F_z (bounds 3–100 ·F_z) and C^y = 10·F_z /rad (bounds 2–40 ·F_z),
        one-sigma 50 % (see :data:`GENERIC_CX_PER_LOAD`, :data:`GENERIC_CY_PER_LOAD`):
        wide enough to hold ice and dry asphalt, so the filter has to find the level.
        """
        b = vehicle.body
        fz_f = b.mass * G * b.lr / b.wheelbase
        fz_r = b.mass * G * b.lf / b.wheelbase
        loads = (fz_f, fz_r, fz_f, fz_r)
        per = (GENERIC_CX_PER_LOAD, GENERIC_CX_PER_LOAD, GENERIC_CY_PER_LOAD, GENERIC_CY_PER_LOAD)
        return cls(nominal=tuple(c[1] * f for c, f in zip(per, loads, strict=True)),  # type: ignore[arg-type]
                   sigma=tuple(GENERIC_REL_SIGMA * c[1] * f for c, f in zip(per, loads, strict=True)),  # type: ignore[arg-type]
                   lower=tuple(c[0] * f for c, f in zip(per, loads, strict=True)),  # type: ignore[arg-type]
                   upper=tuple(c[2] * f for c, f in zip(per, loads, strict=True)))  # type: ignore[arg-type]

    @classmethod
    def for_vehicle(cls, vehicle: Vehicle) -> StiffnessPrior:
        """The vehicle file's ``[stiffness]`` table (±30 %) if present, else :meth:`generic`."""
        s = vehicle.stiffness
        if s is None:
            return cls.generic(vehicle)
        return cls.from_table((s.cx_f, s.cx_r, s.cy_f, s.cy_r))


@dataclass(frozen=True)
class StiffnessConfig:
    """Tuning of the stiffness filters (defaults: 002 Sec. VI and the simulator's sensor model).

    Attributes:
        forgetting: λ of 002 eq. (20), applied once per ``forgetting_period``.
        forgetting_period: s; the time over which the statistics forget by λ (a step of
            length T_s applies λ^(T_s/period)). 0 means one log sample, i.e. 002's
            per-step λ at the log rate.
        resample_threshold: N_thr/N of Algorithm 1, line 8.
        gamma0, nu0: initial NiW statistics γ_0 and ν_0 (ν_0 > 4 so that eq. (27b) exists).
        initial_noise_sd: initial per-step noise one-sigma √diag(Λ_0/(ν_0 − 4)) relative to the
            nominal stiffness (0: the prior sigma, as before); the level's uncertainty is the
            spread of the particles' μ̂_0 (docs/methods_stiffness.md).
        bias_correlation_time: s; the bias update (30) counts one residual per this time
            (its R + d Σ̂ dᵀ + H P_x Hᵀ times τ_c/T_s; 0 is eq. (30) as printed).
        accel_noise, gyro_noise: one-sigma white noise of the IMU, m/s² and rad/s (R).
        accel_bias_sd, gyro_bias_sd: one-sigma of the initial bias, m/s² and rad/s (P_0).
            Zero, with zero random walk, fixes the bias at zero (002 Sec. VI-A's
            simulation, where the bias is set to zero): the bias filter of eq. (29)–(30)
            then never moves and the weights see R alone.
        accel_bias_walk, gyro_bias_walk: bias random walk of eq. (11), m/s²/√s and rad/s/√s (Q).
        model_error: white acceleration noise added to the state prediction
            (m/s², m/s², rad/s²), see :mod:`~vestim.estimators.stiffness.pf`. None on v_x:
            noise there lets each particle trade its v_x (hence its slip λ, eq. (3))
            against its C^x, and on 002's own data it raised the C^x error from 0.8 % to
            4.6 % without helping on the double-track plant (docs/methods_stiffness.md).
            The lateral components are small for the same reason: v_y is what trades the
            front against the rear cornering stiffness (only the understeer combination is
            observable in steady cornering), and 0.2 m/s² let it, and with it the
            front/rear split, wander by ±10–50 % on the cross-plant logs.
            (0, 0, 0) is 002's eq. (9) exactly.
        initial_state_sd: one-sigma of x_0 = [v_x, v_y, ψ̇] (m/s, m/s, rad/s); 002 Sec. VI-A
            uses P_0 = diag(1, 1, (π/180)²).
        wheel_speed_cutoff: Hz, first-order causal low-pass on the axle-mean wheel speeds
            (0 disables; the slip of eq. (3) is noise-sensitive: 0.42 rad/s of wheel-speed
            noise is 0.6 % of slip at 22 m/s).
        attitude_from_rates: measure the roll and pitch gradients of 002 Sec. II-A from the
            log's ``roll_rate`` / ``pitch_rate`` where present (:func:`~vestim.estimators.
            stiffness.inputs.attitude_scale`) instead of taking them from ``[suspension]``.
        attitude_cutoff: Hz, high-pass of that regression (removes the integrated gyro bias).
        attitude_prior_weight: s·(m/s²)², weight of the ``[suspension]`` gradient in it.
        roll_crossover: Hz; with ``attitude_from_rates`` and a ``roll_rate`` channel, a_y is
            compensated with the roll angle of a complementary filter (the steady-state
            gradient below this frequency, the integrated roll rate above it; :func:`~vestim.
            estimators.stiffness.inputs.roll_compensated`). 0 divides by 1 + c_φ g only
            (002 Sec. II-A).
        settle_time: s; the filter is not active during the first ``settle_time`` of the
            log, while the state posterior converges from P_0 (a 1 m/s error of v_x is a
            4.5 % slip error at 22 m/s, which the statistics would otherwise learn as ΔC^x).
        v_min: m/s; below it the filter is not active (eq. (4) is singular at standstill).
        delta_min: rad; |δ| at or above it activates the filter (lateral excitation).
        slip_min: |wheel-speed slip proxy| at or above it activates the filter.
        stiffness_walk: EKF only: random walk of the stiffness states, relative to the
            nominal value per √s.
        augpf_mean_walk: AUGPF only: random-walk one-sigma of the noise mean per step,
            relative to the nominal value (002 Sec. VI-A: 2 % of the true value).
        augpf_var_walk: AUGPF only: relative one-sigma of the inverse-gamma step of each
            noise variance (002 Sec. VI-A: 1 %).
        augpf_initial_sd: AUGPF only: initial one-sigma of the stiffness noise w around its
            mean, relative to the nominal value (the spread of the means is the prior sigma).
        rls_forgetting: RLS only: forgetting factor of the recursive least squares.
        rls_cutoff: RLS only: Hz, low-pass applied to both sides of the regression.
        gyro_lookahead: Algorithm 1 only: condition the draw of w_k on the gyro sample of
            step k + 1 (``pf.alg1_kernel``, docs/methods_stiffness.md).
    """

    forgetting: float = 0.99
    forgetting_period: float = 0.0
    resample_threshold: float = 1.0 / 3.0
    gamma0: float = 0.1
    initial_noise_sd: float = 0.1
    nu0: float = 20.0
    accel_noise: float = 0.05
    gyro_noise: float = 0.003
    accel_bias_sd: float = 0.05
    gyro_bias_sd: float = 0.002
    accel_bias_walk: float = 3e-4
    bias_correlation_time: float = 5.0
    gyro_bias_walk: float = 1.5e-5
    model_error: tuple[float, float, float] = (0.0, 0.05, 0.05)
    initial_state_sd: tuple[float, float, float] = (1.0, 1.0, math.pi / 180.0)
    wheel_speed_cutoff: float = 8.0
    attitude_from_rates: bool = True
    attitude_cutoff: float = 0.1
    attitude_prior_weight: float = 1.0
    roll_crossover: float = 0.5
    settle_time: float = 1.0
    v_min: float = 5.0
    delta_min: float = 0.002
    slip_min: float = 0.002
    stiffness_walk: float = 0.02
    augpf_mean_walk: float = 0.02
    augpf_var_walk: float = 0.01
    augpf_initial_sd: float = 0.05
    rls_forgetting: float = 0.999
    rls_cutoff: float = 5.0
    gyro_lookahead: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            if not all(isinstance(v, int | float) and math.isfinite(v) and v >= 0 for v in values):
                raise ValueError(f"StiffnessConfig.{f.name} = {value!r} must be finite and >= 0")
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"StiffnessConfig.forgetting = {self.forgetting} must lie in (0, 1]")
        if not 0.0 < self.rls_forgetting <= 1.0:
            raise ValueError(f"StiffnessConfig.rls_forgetting = {self.rls_forgetting} must lie in (0, 1]")
        if not 0.0 < self.resample_threshold <= 1.0:
            raise ValueError("StiffnessConfig.resample_threshold = "
                             f"{self.resample_threshold} must lie in (0, 1]")
        if self.nu0 <= 4.0:
            raise ValueError(f"StiffnessConfig.nu0 = {self.nu0} must exceed 4 (002 eq. (27b))")
        if self.gamma0 <= 0.0:
            raise ValueError(f"StiffnessConfig.gamma0 = {self.gamma0} must be > 0")
        if self.accel_noise <= 0.0 or self.gyro_noise <= 0.0:
            raise ValueError("StiffnessConfig.accel_noise and gyro_noise must be > 0 (R ≻ 0)")
        if len(self.model_error) != 3 or len(self.initial_state_sd) != 3:
            raise ValueError("StiffnessConfig.model_error and initial_state_sd need three values "
                             "(v_x, v_y, yaw rate)")
