"""Reference-speed Kalman filter: what an ABS/ESC team ships without a tire model.

State x = [v_x, v_y, b_x, b_y, b_r]: CG velocity in the body frame (m/s), the biases of
the longitudinal and lateral kinematic accelerations (m/s²; accelerometer bias plus
the road grade's g·sin γ or bank's g·sin β, which the IMU cannot tell apart) and the
yaw-gyro bias (rad/s). Process (000 eq. (15) with the lateral equation):
    v̇_x = f_x − b_x + (r − b_r) v_y,    v̇_y = f_y − b_y − (r − b_r) v_x,    ḃ = w_b,
with f the IMU specific force rotated to the road plane by the body angles.

Measurements, sequential scalar updates per sample:
* each wheel's speed mapped to the CG, v_i = R ω_i cos δ_i − v_yt,i sin δ_i + r y_i
  (v_yt,i from the current v_y; a NaN ω_i is no measurement: a log without wheel speeds
  runs on the extra CG-speed measurements alone, its lateral part unchanged), with a
  variance that grows with the evidence of slip of that wheel:
    - its use of friction |μ_x,i| (drive or brake force per load, from the force stage),
    - ω̇ inconsistent with the acceleration, |R ω̇_i − a_x| over a 0.1 s window,
    - innovations of the sign slip produces (positive while driving, negative
      while braking) are inflated quadratically,
  and innovation gating (rejected beyond ``gate`` standard deviations);
* optional extra CG-speed measurements (n, m) with their variances — the
  pipeline's fusion feeds the corner-based estimates here;
* each axle's slip angle from its estimated lateral force and the nominal small-slip
  cornering stiffness (α = −F_y/C_y): v_y = v_x(α_f + δ) − l_f r and v_y = v_x α_r + l_r r
  (single-track kinematics), pseudo-measurements whose σ grows with the slip angle
  (stiffness uncertainty) and the sideslip acceleration (sliding), gated at ``gate_vy``.
  The friction is unknown, so an axle beyond the linear range, or whose v_y disagrees with
  the other axle's, gives only a one-sided bound; v_y then comes from the integral, whose
  drift b_y (learnt while the tires were linear) holds down. Both axles rejected for
  ``reacquire_s`` while they agree and are below the friction the car has demonstrated
  re-acquire them (the integral drifted, not the tires).

v_y's process noise is the log's own: the measured white noise of f_y and its relative
model error (scale, roll gravity), so a noisy or vibrating IMU leans on the tire model.

A wheel whose measurement is rejected or inflated leaves the filter to the
acceleration integral, whose drift the bias state limits.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.filters.kalman import direct_update
from vestim.models.kinematics import middle_wheel_speed
from vestim.params import check_ranges, pack

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

VX, VY, BX, BY, BR = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class ReferenceParams:
    """Tuning of the reference filter (one set for every maneuver).

    Attributes:
        q_vx, q_vy: process intensities of v_x, v_y, (m/s)²/s (IMU noise and model error).
        q_vx_speed: q_vx where f_x is a speed's derivative (a log without ``ax``), (m/s)²/s:
            that derivative lags by 0.1 s (wheel speeds) to 0.5 s (GNSS fixes). 0.2 (10 ×
            q_vx): on the crossplant logs without ax its v_x RMSE is 0.080 (x07), 0.046 (x11)
            m/s against 0.102, 0.069 at q_vx, and 0.088 against 0.73 on x07 without wheel
            speeds either (GNSS fixes); x05, x08 without wheel speeds 0.043 against 0.033.
        q_bias: random-walk intensity of b_x, (m/s²)²/s (grade changes, bias drift).
        r_wheel: wheel-speed variance at no slip, (m/s)² (sensor noise, radius error).
        slip_bias: the expected slip removed from each wheel's speed, 1/C (C: a normalised
            longitudinal slip stiffness, dF_x/dλ / F_z): v_wheel − slip_bias·μ_x·|v̂_x|. A
            tire's slip at force μ_x F_z in its linear range is λ = μ_x/C; 0.05 is C = 20,
            the passenger-car value (PAC2002 p_kx1 ≈ 15–25). It is a prior, not this car's
            tire: the vehicle file's nominal LuGre values (σ0x/κx = 75) are not used for it,
            as no independent log is that stiff (the crossplant PAC2002 tire has
            p_kx1 = 22.3). Braking logs: crossplant x04 CG v_x 0.23 → 0.06 %, x07 0.38 →
            0.02 % (k_mu 0.05 both); RAV4 (no gnss_speed) 0.153 → 0.142 m/s. The
            simulator's LuGre tire is C = 75: its AWD accel_brake gets 0.31 → 0.58 %.
        k_mu: slip-evidence gain: σ grows by k_mu·|μ_x|·|v| (m/s per unit μ_x); 0.05: the
            σ of the expected slip is 100 % of it (C from 10 to ∞). Beyond the linear range
            (a tire near its unknown friction limit) the slip grows faster; the ω̇ evidence
            (k_acc) and the slip-signed inflation (slip_sign) catch it. 1 (σ = |μ_x| v: C = 1)
            de-weighted every wheel while braking at 0.2 g, and v_x became the a_x integral
            with its grade and pitch error: RAV4 0.255 m/s RMSE (+1.1 m/s in a 5 s stop),
            where the mean wheel speed has 0.156.
        k_acc: slip-evidence gain on |R ω̇ − a_x|, s (m/s per m/s²).
        slip_sign: innovation (m/s) at which a slip-signed innovation doubles σ.
        gate: innovation gate in standard deviations.
        soft_gate: normalised innovation (standard deviations) beyond which a wheel that
            disagrees with v̂_x while another wheel agrees enters as a slipping wheel: its σ
            raised so that its innovation is ``soft_gate`` σ, the excess as persistent slip
            (τ_wheel/T_s). A spinning wheel at the turn of its oscillation shows no torque
            or ω̇ evidence for a few samples; 2 σ: crossplant x02 (RWD launch on ice, the
            rear wheels 60 % above the speed at their slowest) CG v_x 0.254 → 0.123 %.
        r_vy: variance of the axles' v_y pseudo-measurements at zero slip angle, (m/s)².
        k_vy: growth of their σ with the sideslip acceleration |f_y − b_y − r v_x|, s,
            counted beyond 2σ of f_y's measured white noise (a vibrating accelerometer
            is no evidence of a slide; with the raw value, campaign seed 1 had v_y within
            target on 4 fewer scenarios and β on 4 fewer, issue 29, session 15).
        bias_max: bound on |b_x|, m/s² (sensor bias plus a grade of about 5 %).
        q_bias_y: random-walk intensity of b_y, (m/s²)²/s.
        bias_y_max: bound on |b_y|, m/s² (sensor biases, r-gyro bias × v_x, bank of ~5 %).
        k_rel: relative error of the cornering stiffness (σ of the pseudo-measurement grows by
            k_rel·|v_x α|). 0.5: the effective axle stiffness of the independent logs is
            15–46/rad where the file says 15 and the online identification reaches 15–24
            (benchmarks/lateral_study.py); 0.3 was tighter than that.
        gate_vy: innovation gate of the v_y pseudo-measurements, standard deviations.
        tau_vy: correlation time of their error, s (see :func:`_lateral_update`); 0.1 s:
            with the stiffness identified online the bound is no longer off by the nominal
            stiffness for seconds at a time (1 s let v_y drift 0.06 m/s on the crossplant
            slalom, x08).
        side_vy: innovation (m/s) on the allowed side of the linear-tire bound at which its
            slip-dependent σ doubles.
        tau_wheel: correlation time of a wheel's slip error, s: the slip-evidence part of
            its σ enters with the variance inflated by τ/T_s (0: white).
        acc_dead: dead zone of the |R ω̇ − a_x| evidence, m/s² (the wheel-speed noise makes
            ω̇ over the window noisy: σ ≈ 2 m/s² for the simulator's sensors at 200 Hz).
        q_gyro_bias: random-walk intensity of the yaw-gyro bias b_r, (rad/s)²/s.
        gyro_bias_sd: prior one-sigma of b_r, rad/s. 0.006 (0.34°/s): a MEMS yaw gyro's
            turn-on bias is specified at 0.3–0.5°/s, and the crossplant campaign draws it from
            U(−0.01, 0.01) rad/s (σ 0.0058); 0.003 held b_r back from biases of that size,
            which at 20 m/s are 0.2 m/s² of v̇_y (campaign β within target 31 → 33 of 48,
            crossplant and Revs within 0.01°).
        torque_dead: |torque| (N m) below which a wheel counts as neither driven nor braked
            for the slip-signed inflation (torque-sensor noise at standstill, σ ≈ 6 N m,
            would otherwise make the inflation one-sided at random and bias b_x).
        torque_dead_mu: the same dead zone as a share of the wheel's static load, R·m g/4
            (the filter takes the larger): a torque that asks under 5 % of the load spins
            no wheel on any road a car drives on (glare ice: μ ≈ 0.05–0.1), while the
            steady torque of cruising against the drag (μ ≈ 0.02) inflated a driven wheel's
            noise above v̂_x and not below it, σ that then entered as persistent slip
            (τ_wheel/T_s): v̂_x ran 0.3 m/s low on the simulator's AWD runs (wet lane change
            CG v_x 1.25 → 0.08 %, step steer v_y 17.1 → 2.1 %). For the simulator's SUV it
            is 92 N m, for the crossplant's Ford Escort 52 N m; the crossplant RWD ice launch
            (x02) pays 0.21 → 0.26 % CG v_x (its first 0.1 s of spin-up is trusted longer).
        k_comb: slip ratio λ_c of an axle's wheels at which the v_y bound's one-sidedness
            doubles (side_vy / (1 + (λ/λ_c)²)): a tire in longitudinal slip is in combined
            slip and makes less lateral force than the linear tire says.
        alpha_lin: linear-tire slip angle |α| (rad) at which the v_y pseudo-measurements are
            half way from a value (k_rel, tau_vy, side_vy, gate_vy: the linear range, with the
            stiffness identified online) to a bound (the ``*_sat`` values: a saturating tire
            of unknown friction), blend 1/(1 + (α/α_lin)⁴).
        demo_ratio: re-acquisition (``reacquire_s``) counts a rejected sample only while
            both axles are below demo_ratio·α_d, α_d the largest |α| of either axle so far
            (forgotten over ``demo_tau``, at least ``alpha_lin``): the friction the car has
            demonstrated on this road. An axle near it may be sliding, and a slide's
            linear-tire value is wrong (0.8 let the simulator's brake-in-turn on ice, both
            axles sliding with no pair gap, be pulled to it: v_y 2.4 → 18.9 %). The same
            evidence in place of α_lin in the blend (the σ of the bound) took the Revs log's
            β to 1.93° (2.17 with α_lin) but left the simulator's low-μ slides to the linear
            tire (v_y 3 → 57 %).
        demo_tau: forgetting time of the demonstrated slip angle, s.
        k_rel_sat, tau_vy_sat, side_vy_sat, gate_vy_sat: k_rel, tau_vy, side_vy, gate_vy of a
            saturating axle.
        pair_gap: gap between the front and rear linear-tire v_y (m/s) at which both are
            half way from a value to a bound (blend 1/(1 + (gap/pair_gap)²), times the
            slip-angle blend of ``alpha_lin``).
        sigma_gnss: one-sigma of a ``gnss_speed`` fix (brought forward by its latency) as a
            white CG-speed measurement, m/s (the pipeline undoes the τ_wheel/T_s inflation of
            extra measurements for it). The RAV4 log's fixes scatter by 0.077 m/s against
            the pose reference once the latency is removed.
        sigma_vehicle_speed: one-sigma of a dense CAN ``vehicle_speed`` as a CG-speed
            measurement, m/s, used only in a log without wheel speeds. Its error (the ESC's
            own reference speed: radius error, quantisation) persists like a wheel's, so it
            enters with the τ_wheel/T_s inflation of every extra measurement.
        sigma_corner_slip: one-sigma (m/s) of the fused pipeline's corner-observer CG speed,
            which enters only while ≥ 3 corners are in high slip (before the τ/T_s
            inflation). 3 m/s: with 1 m/s the corner KF's tire-model bias in moderate
            all-wheel slip cost up to 0.4 point of CG v_x NRMS over the reference filter
            alone (seeds 1–3); at 3 m/s it is within 0.13 point everywhere.
        window: samples of the ω̇ difference.
        fy_noise_tau: time constant of the online estimate of f_y's white noise, s: the
            variance of its sample-to-sample difference over 2, averaged over this time. It
            enters v_y's process noise as σ² T_s per second, so that the log's own sensor
            noise (0.05 m/s² on a lab IMU, 1–4 m/s² of vibration in a car) sets how fast the
            integral loses its information, not a constant.
        fy_scale_sd: relative one-sigma of f_y as a model of v̇_y + r v_x: an accelerometer's
            scale and the gravity of an unknown roll (0–10°/g: 0–17 % of a_y) that the
            attitude stage removes only approximately. It enters v_y's process noise as
            2 τ (σ_s f_y)² per second (a Gauss–Markov error of correlation time τ =
            ``tau_fy``).
        tau_fy: correlation time of that f_y error, s.
        reacquire_s: time (s) after which a measurement kind that has been rejected at every
            sample (the v_y pseudo-measurements of both axles, or every CG-speed measurement
            of a log without wheel speeds) is taken as evidence that the filter, not the
            measurement, has drifted: its state's variance is raised to the squared
            innovation, and the next sample is accepted (the wheel speeds' restart, for the
            other measurements).
    """

    q_vx: float = 0.02
    q_vy: float = 1.0e-4
    q_bias: float = 2.0e-4
    r_wheel: float = 0.05
    k_mu: float = 0.05
    slip_bias: float = 0.05
    k_acc: float = 0.3
    slip_sign: float = 0.3
    gate: float = 5.0
    soft_gate: float = 2.0
    r_vy: float = 0.0025
    k_vy: float = 0.1
    bias_max: float = 0.5
    q_bias_y: float = 1.0e-5
    bias_y_max: float = 0.5
    k_rel: float = 0.5
    gate_vy: float = 6.0
    tau_vy: float = 0.1
    side_vy: float = 1.0
    tau_wheel: float = 1.0
    acc_dead: float = 3.0
    q_gyro_bias: float = 1.0e-9
    gyro_bias_sd: float = 0.006
    torque_dead: float = 20.0
    torque_dead_mu: float = 0.05
    k_comb: float = 0.1
    alpha_lin: float = 0.015
    k_rel_sat: float = 1.0
    tau_vy_sat: float = 1.0
    side_vy_sat: float = 0.05
    gate_vy_sat: float = 3.0
    pair_gap: float = 0.2
    window: int = 20
    sigma_corner_slip: float = 3.0
    sigma_gnss: float = 0.1
    sigma_vehicle_speed: float = 0.1
    q_vx_speed: float = 0.2
    fy_noise_tau: float = 2.0
    fy_scale_sd: float = 0.02
    tau_fy: float = 1.0
    reacquire_s: float = 1.0
    demo_ratio: float = 0.5
    demo_tau: float = 60.0

    def __post_init__(self) -> None:
        check_ranges(self, "reference", positive=(
            "r_wheel", "gate", "soft_gate", "r_vy", "gate_vy", "alpha_lin", "gate_vy_sat", "pair_gap",
            "k_comb", "window", "sigma_corner_slip", "sigma_gnss", "sigma_vehicle_speed",
            "fy_noise_tau", "tau_fy", "reacquire_s", "demo_tau"),
            nonnegative=[f.name for f in fields(self)])


@dataclass(frozen=True)
class StiffnessParams:
    """Online normalised cornering stiffness c = C_y/ΣF_z of :func:`axle_slip_angles`.

    Attributes:
        prior_sd: relative one-sigma of the prior compliance 1/c₀ (c₀ = σ0y/κy of the
            [tire] table, which is a nominal value, not this car's tire).
        sigma_kappa: one-sigma of the slip-difference regression's error, rad (gyro noise,
            camber thrust and roll steer that the single-track kinematics leave out).
        tau: forgetting time of the regression, s (the road or tire may change).
        mu_linear: |μ_y| of either axle above which a sample is left out (off the linear
            range the secant stiffness is lower than the small-slip one).
        v_min: speed below which a sample is left out, m/s.
        c_min, c_max: physical bounds of c, 1/rad (passenger-car tires: about 10–30).
        tau_hp: time constant of the high-pass applied to both sides of the regression, s:
            it keeps the yaw transients and removes what drifts slowly with the lateral
            acceleration (camber thrust, roll steer, the onset of saturation in a ramp),
            which would otherwise be read as compliance.
        tau_lp: time constant of the low-pass applied to both sides, s: noise on the
            estimated μ_yr − μ_yf (the regressor) would bias the compliance towards 0.
        e_robust: band-passed residual (rad) at which a sample's weight is halved (Cauchy):
            the onset of saturation or of combined slip moves L r/v_x − δ where the linear
            tire does not.
    """

    prior_sd: float = 0.3
    sigma_kappa: float = 0.01
    tau: float = 20.0
    mu_linear: float = 0.3
    v_min: float = 5.0
    c_min: float = 8.0
    c_max: float = 30.0
    tau_hp: float = 1.0
    tau_lp: float = 0.1
    e_robust: float = 0.002

    def __post_init__(self) -> None:
        check_ranges(self, "cornering", positive=("prior_sd", "sigma_kappa", "tau", "c_min",
                                                  "tau_hp", "tau_lp", "e_robust"),
                     nonnegative=("mu_linear", "v_min"), finite=True)
        if not self.c_max > self.c_min:
            raise ValueError(f"cornering c_max = {self.c_max} must be > c_min = {self.c_min}")


class StiffnessKernelParams(NamedTuple):
    """Parameters of :func:`stiffness_step`, made by :func:`stiffness_params` (``pack`` of a
    :class:`StiffnessParams`).

    Attributes:
        w0: prior compliance 1/c₀, rad.
        prior_weight: weight of the prior, (σ_κ c₀/prior_sd)² (the prior counts as that many
            samples of unit regressor).
        tau, mu_linear, v_min, c_min, c_max, tau_hp, tau_lp, e_robust: as in
            :class:`StiffnessParams`.
        radius: wheel radius R, m.
        wheelbase: L = l_f + l_r, m.
    """

    w0: float
    prior_weight: float
    tau: float
    mu_linear: float
    v_min: float
    c_min: float
    c_max: float
    radius: float
    wheelbase: float
    tau_hp: float
    tau_lp: float
    e_robust: float


class StiffnessState(NamedTuple):
    """State of :func:`stiffness_step`, each a 1-element array (in place).

    Attributes:
        x_slow, y_slow: the high-pass's slow part of the low-passed regressor μ_yr − μ_yf and
            of the regressand L r/v_x − δ (subtracted), rad.
        linear: a linear-range sample has been seen (the band-pass starts from it).
        sxx, sxy: exponentially forgotten weighted sums Σ x², Σ x y of the band-passed pair.
        t_prev: time of the previous sample, s.
        started: a sample has been seen.
        x_lp, y_lp: the low-passed regressor and regressand.
    """

    x_slow: np.ndarray
    y_slow: np.ndarray
    linear: np.ndarray
    sxx: np.ndarray
    sxy: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    x_lp: np.ndarray
    y_lp: np.ndarray


def stiffness_params(c0: float, p: StiffnessParams, radius: float,
                     wheelbase: float) -> StiffnessKernelParams:
    """Parameters of :func:`stiffness_step` from the nominal c₀ (1/rad), R and L (m)."""
    return pack(StiffnessKernelParams, p, w0=1.0 / c0,
                prior_weight=(p.sigma_kappa * c0 / p.prior_sd) ** 2, radius=radius,
                wheelbase=wheelbase)


def new_stiffness_state() -> StiffnessState:
    """A fresh :class:`StiffnessState` (nothing seen)."""
    return StiffnessState(*(np.zeros(1) for _ in StiffnessState._fields))


def clear_state(st: tuple[np.ndarray, ...]) -> None:
    """Zero every array of a stage's state NamedTuple in place (its ``reset``)."""
    for a in st:
        a[...] = 0


@njit(**_JIT)
def _stiffness_rows(prm: StiffnessKernelParams, st: StiffnessState, start: int, stop: int,
                    t: np.ndarray, omega: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                    fy: np.ndarray, fz: np.ndarray, out: np.ndarray, out_c: np.ndarray) -> None:
    """Rows [start, stop) of :func:`axle_slip_angles`, the arrays of ``st`` taken once per
    call (see :func:`_reference_rows`)."""
    (x_slow, y_slow, linear, sxx, sxy, t_prev, started, x_lp, y_lp) = st
    for k in range(start, stop):
        fzf = fz[k, 0] + fz[k, 1]
        fzr = fz[k, 2] + fz[k, 3]
        mu_f = (fy[k, 0] + fy[k, 1]) / fzf if fzf > 1.0 else np.nan
        mu_r = (fy[k, 2] + fy[k, 3]) / fzr if fzr > 1.0 else np.nan
        dt = t[k] - t_prev[0] if started[0] == 1.0 else 0.0
        lam = np.exp(-dt / prm.tau)
        t_prev[0] = t[k]
        started[0] = 1.0
        sxx[0] *= lam
        sxy[0] *= lam
        w0, p0 = prm.w0, prm.prior_weight
        v = middle_wheel_speed(omega, k, prm.radius)
        if v > prm.v_min and abs(mu_f) < prm.mu_linear and abs(mu_r) < prm.mu_linear:
            x = mu_r - mu_f
            y = prm.wheelbase * yaw_rate[k] / v - 0.5 * (delta[k, 0] + delta[k, 1])
            if linear[0] == 0.0:  # first linear sample: the band-pass starts from it
                x_slow[0], y_slow[0], linear[0], x_lp[0], y_lp[0] = x, y, 1.0, x, y
            g = min(dt / prm.tau_lp, 1.0)
            x_lp[0] += g * (x - x_lp[0])
            y_lp[0] += g * (y - y_lp[0])
            g = min(dt / prm.tau_hp, 1.0)
            x_slow[0] += g * (x_lp[0] - x_slow[0])
            y_slow[0] += g * (y_lp[0] - y_slow[0])
            x = x_lp[0] - x_slow[0]
            y = y_lp[0] - y_slow[0]
            # Cauchy weight on the residual against the current compliance: the onset of
            # saturation or combined slip makes y jump where x does not, and would be read
            # as a stiff tire.
            e = (y - x * (sxy[0] + p0 * w0) / (sxx[0] + p0)) / prm.e_robust
            wgt = 1.0 / (1.0 + e * e)
            sxx[0] += wgt * x * x
            sxy[0] += wgt * x * y
        comp = (sxy[0] + p0 * w0) / (sxx[0] + p0)
        c = min(max(1.0 / comp if comp > 0.0 else prm.c_max, prm.c_min), prm.c_max)
        out_c[k] = c
        out[k, 0] = -mu_f / c
        out[k, 1] = -mu_r / c


@njit(**_JIT)
def stiffness_step(prm: StiffnessKernelParams, st: StiffnessState, k: int, t: np.ndarray,
                   omega: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray, fy: np.ndarray,
                   fz: np.ndarray, out: np.ndarray, out_c: np.ndarray) -> None:
    """Sample ``k`` of :func:`axle_slip_angles` (its inputs and outputs), in place on ``st``."""
    _stiffness_rows(prm, st, k, k + 1, t, omega, yaw_rate, delta, fy, fz, out, out_c)


@njit(**_JIT)
def axle_slip_angles(prm: StiffnessKernelParams, st: StiffnessState, t: np.ndarray,
                     omega: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray, fy: np.ndarray,
                     fz: np.ndarray, out: np.ndarray, out_c: np.ndarray) -> None:
    """Axle slip angles α = −F_y/(c ΣF_z) (n, 2) [front, rear], rad, the linear-tire input of
    the v_y bounds, with the normalised cornering stiffness c identified online.

    The single-track kinematics fix the difference of the axle slip angles without v_y:
    α_f − α_r = L r/v_x − δ (000 eq. (16)'s slip angles, spec sign), and a linear tire
    gives α = −w μ_y with the compliance w = 1/c. So
        L r/v_x − δ = w (μ_yr − μ_yf) + b,
    a regression for w (b takes a steering offset and the gyro bias over speed) in samples
    where both axles are in their linear range. It is solved in closed form from
    exponentially forgotten sums (time constant τ) with the Gaussian prior w₀ = 1/c₀ of
    weight (σ_κ/σ_w)² (``prm`` from :func:`stiffness_params`). Only yaw transients excite
    it: in steady cornering μ_yf ≈ μ_yr and c stays where the last transient left it.
    ``st`` (:class:`StiffnessState`) is advanced in place; ``out_c`` (n,) the c used.
    NaN where ΣF_z ≤ 1 N (lifted axle). :func:`stiffness_step` for each sample.
    """
    _stiffness_rows(prm, st, 0, t.shape[0], t, omega, yaw_rate, delta, fy, fz, out, out_c)


@dataclass(frozen=True)
class RadiusParams:
    """Online wheel-radius scale and GNSS latency from a sparse ``gnss_speed``
    (:func:`gnss_calibration`).

    Attributes:
        prior_fixes: weight of the prior scale 1 (the file's wheel_radius) and latency 0, in
            fixes at ``prior_speed`` and ``prior_accel``.
        prior_speed: speed of those prior fixes, m/s.
        prior_accel: acceleration of those prior fixes, m/s² (sets the latency prior's weight).
        tau: forgetting time, s (tire wear, pressure and load change slowly).
        v_min: speed below which a fix is not used, m/s (GNSS speed noise dominates).
        a_max: |dv_w/dt| above which a fix is not used, m/s² (wheel slip).
        tau_acc: time constant of the low-pass on the wheel-speed derivative, s.
        s_min, s_max: physical bounds of the scale (a radius off by more than 8 % is a wrong
            vehicle file, not tire growth).
        latency_max: bound of the receiver latency, s.
    """

    prior_fixes: float = 20.0
    prior_speed: float = 10.0
    prior_accel: float = 1.0
    tau: float = 600.0
    v_min: float = 3.0
    a_max: float = 3.0
    tau_acc: float = 0.05
    s_min: float = 0.92
    s_max: float = 1.08
    latency_max: float = 0.5

    def __post_init__(self) -> None:
        check_ranges(self, "radius", positive=("prior_fixes", "prior_speed", "prior_accel", "tau",
                                               "a_max", "tau_acc", "s_min"),
                     nonnegative=("v_min", "latency_max"), finite=True)
        if not self.s_max > self.s_min:
            raise ValueError(f"radius s_max = {self.s_max} must be > s_min = {self.s_min}")


class RadiusKernelParams(NamedTuple):
    """Parameters of :func:`radius_step`, made by :func:`radius_params` (``pack`` of a
    :class:`RadiusParams`).

    Attributes:
        radius: the vehicle file's wheel radius R, m.
        w_s: weight of the prior scale 1, prior_fixes·prior_speed², (m/s)².
        tau, v_min, a_max, s_min, s_max, tau_acc, latency_max: as in :class:`RadiusParams`.
        w_c: weight of the prior c = s L = 0, prior_fixes·prior_accel², (m/s²)².
    """

    radius: float
    w_s: float
    tau: float
    v_min: float
    a_max: float
    s_min: float
    s_max: float
    w_c: float
    tau_acc: float
    latency_max: float


class RadiusState(NamedTuple):
    """State of :func:`radius_step`, each a 1-element array (in place).

    Attributes:
        s_vv, s_va, s_aa, s_gv, s_ga: exponentially forgotten sums Σ v_w², Σ v_w v̇_w,
            Σ v̇_w², Σ g v_w, Σ g v̇_w over the fixes used.
        t_prev: time of the previous sample, s.
        started: a sample has been seen.
        v_prev: v_w of the previous sample, m/s.
        a_w: low-passed v̇_w, m/s².
    """

    s_vv: np.ndarray
    s_va: np.ndarray
    s_aa: np.ndarray
    s_gv: np.ndarray
    s_ga: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    v_prev: np.ndarray
    a_w: np.ndarray


def radius_params(p: RadiusParams, radius: float) -> RadiusKernelParams:
    """Parameters of :func:`radius_step` for the file's wheel radius (m)."""
    return pack(RadiusKernelParams, p, radius=radius, w_s=p.prior_fixes * p.prior_speed**2,
                w_c=p.prior_fixes * p.prior_accel**2)


def new_radius_state() -> RadiusState:
    """A fresh :class:`RadiusState` (nothing seen)."""
    return RadiusState(*(np.zeros(1) for _ in RadiusState._fields))


@njit(**_JIT)
def _radius_rows(prm: RadiusKernelParams, st: RadiusState, start: int, stop: int,
                 t: np.ndarray, omega: np.ndarray, gnss: np.ndarray, out_scale: np.ndarray,
                 out_latency: np.ndarray, out_speed: np.ndarray) -> None:
    """Rows [start, stop) of :func:`gnss_calibration`, the arrays of ``st`` taken once per
    call (see :func:`_reference_rows`)."""
    (s_vv, s_va, s_aa, s_gv, s_ga, t_prev, started, v_prev, a_lp) = st
    for k in range(start, stop):
        v_w = middle_wheel_speed(omega, k, prm.radius)
        if started[0] == 1.0:
            dt = t[k] - t_prev[0]
            lam = np.exp(-dt / prm.tau)
            s_vv[0] *= lam
            s_va[0] *= lam
            s_aa[0] *= lam
            s_gv[0] *= lam
            s_ga[0] *= lam
            if dt > 0:
                g_lp = min(dt / prm.tau_acc, 1.0)
                a_lp[0] += g_lp * ((v_w - v_prev[0]) / dt - a_lp[0])
        t_prev[0] = t[k]
        started[0] = 1.0
        v_prev[0] = v_w
        a_w = a_lp[0]
        g = gnss[k]
        if not np.isnan(g) and v_w > prm.v_min and abs(a_w) < prm.a_max:
            s_vv[0] += v_w * v_w
            s_va[0] += v_w * a_w
            s_aa[0] += a_w * a_w
            s_gv[0] += g * v_w
            s_ga[0] += g * a_w
        # Normal equations for (s, c) with regressors (v_w, −v̇_w) and the priors.
        m11 = s_vv[0] + prm.w_s
        m12 = -s_va[0]
        m22 = s_aa[0] + prm.w_c
        b1 = s_gv[0] + prm.w_s
        b2 = -s_ga[0]
        det = m11 * m22 - m12 * m12
        sc = (b1 * m22 - m12 * b2) / det
        c = (m11 * b2 - m12 * b1) / det
        sc = min(max(sc, prm.s_min), prm.s_max)
        lat = min(max(c / sc, 0.0), prm.latency_max)
        out_scale[k] = sc
        out_latency[k] = lat
        out_speed[k] = g + lat * sc * a_w if not np.isnan(g) else np.nan


@njit(**_JIT)
def radius_step(prm: RadiusKernelParams, st: RadiusState, k: int, t: np.ndarray,
                omega: np.ndarray, gnss: np.ndarray, out_scale: np.ndarray,
                out_latency: np.ndarray, out_speed: np.ndarray) -> None:
    """Sample ``k`` of :func:`gnss_calibration` (its inputs and outputs), in place on ``st``."""
    _radius_rows(prm, st, k, k + 1, t, omega, gnss, out_scale, out_latency, out_speed)


@njit(**_JIT)
def gnss_calibration(prm: RadiusKernelParams, st: RadiusState, t: np.ndarray,
                     omega: np.ndarray, gnss: np.ndarray, out_scale: np.ndarray,
                     out_latency: np.ndarray, out_speed: np.ndarray) -> None:
    """Effective-radius scale s (R_eff = s R) and receiver latency L from the GNSS speed.

    A fix g_k is the speed L seconds ago: g_k ≈ s (v_w − L v̇_w) at its sample (v_w: the
    mean R ω of the two middle wheels, robust to one slipping wheel; v̇_w its derivative,
    low-passed over τ_acc). Least squares in (s, c = s L) with exponential forgetting and
    the priors s = 1, c = 0 (weights W_s in (m/s)², W_c in (m/s²)²), L clipped to
    [0, L_max], s to [s_min, s_max]. Without fixes s = 1 and L = 0. ``out_speed`` is the fix
    brought to its own sample, g + L v̇_w (NaN between fixes): the CG-speed measurement.
    The RAV4 log: s 1.0088 (its CAN wheel speeds read 0.86 % low), L 0.16 s.
    ``prm`` from :func:`radius_params`; ``st`` (:class:`RadiusState`) is advanced in place.
    :func:`radius_step` for each sample.
    """
    _radius_rows(prm, st, 0, t.shape[0], t, omega, gnss, out_scale, out_latency, out_speed)


@njit(**_JIT)
def _lateral_update(x: np.ndarray, P: np.ndarray, z: float, alpha: float, r_white: float,
                    sig_col: float, inflate: float, s_side: float, gate: float,
                    work: np.ndarray) -> float:
    """Update of v_y by an axle's linear-tire pseudo-measurement z (m/s).

    Its error has a white part (variance ``r_white``: the lateral-force noise) and a part
    that grows with the slip angle and the sliding (σ ``sig_col``) and persists for about
    a second, so it enters with the variance σ²·``inflate`` (= τ_c/T_s, the samples per
    correlation time: one sample's information per correlation time). A tire's force grows
    less than linearly with its slip angle, so the linear α = −F_y/C under-states |α|:
    z is a bound on v_y (an upper bound when α < 0), and an estimate on the bound's
    allowed side is pulled only weakly (σ_col grows with (innovation/s_side)²). The gate
    compares the innovation with the un-inflated σ. Returns the innovation (NaN if rejected).
    """
    innov = z - x[VY]
    if innov * innov > gate * gate * (P[VY, VY] + r_white + sig_col * sig_col):
        return np.nan
    if (alpha < 0.0 and innov > 0.0) or (alpha > 0.0 and innov < 0.0):
        sig_col *= 1.0 + (innov / s_side) ** 2
    return direct_update(x, P, VY, z, r_white + sig_col * sig_col * inflate, np.inf, work)


class ReferenceKernelParams(NamedTuple):
    """Parameters of :func:`reference_step`, made by :func:`reference_params` (``pack`` of a
    :class:`ReferenceParams` and the vehicle's geometry).

    Attributes:
        q_vx … pair_gap, sigma_corner_slip … demo_tau: the :class:`ReferenceParams` fields of
            the same name (``q_vx`` is ``q_vx_speed`` and ``slip_sign`` ∞ where ``kin_fx``).
        kin_fx: f_x is v̇_x itself, a speed's derivative (a log without ``ax``): the
            prediction leaves out r v_y; else the IMU's specific force.
        radius: wheel radius R, m.
        lf, lr: CG to front / rear axle, m.
        xw, yw: corner positions from the CG (fl, fr, rl, rr), m, (4,) each.
    """

    q_vx: float
    q_vy: float
    q_bias: float
    r_wheel: float
    k_mu: float
    slip_bias: float
    k_acc: float
    slip_sign: float
    gate: float
    soft_gate: float
    r_vy: float
    k_vy: float
    bias_max: float
    q_bias_y: float
    bias_y_max: float
    k_rel: float
    gate_vy: float
    tau_vy: float
    side_vy: float
    tau_wheel: float
    acc_dead: float
    q_gyro_bias: float
    gyro_bias_sd: float
    torque_dead: float
    k_comb: float
    alpha_lin: float
    k_rel_sat: float
    tau_vy_sat: float
    side_vy_sat: float
    gate_vy_sat: float
    pair_gap: float
    sigma_corner_slip: float
    fy_noise_tau: float
    fy_scale_sd: float
    tau_fy: float
    reacquire_s: float
    demo_ratio: float
    demo_tau: float
    kin_fx: bool
    radius: float
    lf: float
    lr: float
    xw: np.ndarray
    yw: np.ndarray


class ReferenceState(NamedTuple):
    """State of :func:`reference_step` (in place); scalars are 1-element arrays.

    Attributes:
        x: (5,) [v_x, v_y, b_x, b_y, b_r] (m/s, m/s², rad/s; indices VX … BR).
        P: (5, 5) its covariance (full: the r-coupling joins v_x and v_y).
        hist: (window, 5) the last ``window`` samples of (t, ω_fl … ω_rr), for ω̇; a ring
            buffer whose oldest row is ``oldest``.
        t_prev: time of the previous sample, s.
        started: the filter has been initialised (bool).
        fx_prev, fy_prev, r_prev: f_x, f_y (m/s²) and the yaw rate (rad/s) of the previous
            sample, held over the prediction interval.
        n_rejected: consecutive samples with every available wheel rejected (int).
        oldest: row of ``hist`` overwritten next (int).
        wheel_v, wheel_slip, wheel_sig: (4,) work arrays of a sample (each wheel's CG speed,
            m/s, its innovation over speed, and its σ, m/s); no memory from one sample to the
            next.
        fy_var: the online estimate of f_y's white-noise variance, (m/s²)².
        t_vy_rejected, t_speed_rejected: time (s) for which every v_y pseudo-measurement
            (counted only while the axles agree and stay below the demonstrated friction),
            and every CG-speed measurement of a log without wheel speeds, has been rejected.
        alpha_demo: the demonstrated slip angle α_d, rad (``demo_ratio``).
        t_vy_unverified: time (s) since a v_y pseudo-measurement was last accepted (v_y is
            the a_y integral alone meanwhile; the consistency monitor's figure).
        work: (2, 5) scratch space of a sample; no memory from one sample to the next.
    """

    x: np.ndarray
    P: np.ndarray
    hist: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    fx_prev: np.ndarray
    fy_prev: np.ndarray
    r_prev: np.ndarray
    n_rejected: np.ndarray
    oldest: np.ndarray
    wheel_v: np.ndarray
    wheel_slip: np.ndarray
    wheel_sig: np.ndarray
    fy_var: np.ndarray
    t_vy_rejected: np.ndarray
    t_speed_rejected: np.ndarray
    alpha_demo: np.ndarray
    t_vy_unverified: np.ndarray
    work: np.ndarray


def reference_params(p: ReferenceParams, radius: float, lf: float, lr: float, xw: np.ndarray,
                     yw: np.ndarray, fx_from_speed: bool = False,
                     mass: float = 0.0) -> ReferenceKernelParams:
    """Parameters of :func:`reference_step` for the tuning ``p`` and the geometry (m).

    ``fx_from_speed`` (a log without ``ax``, see :meth:`ReferenceFilter.advance`): ``kin_fx``
    set, ``q_vx`` = ``q_vx_speed`` and ``slip_sign`` = ∞ (no slip-signed inflation).
    ``mass`` (kg; 0: unknown) sets the load share of the torque dead zone
    (``torque_dead_mu``)."""
    speed = {"kin_fx": True, "q_vx": p.q_vx_speed, "slip_sign": np.inf} if fx_from_speed else {
        "kin_fx": False}
    torque_dead = max(p.torque_dead, p.torque_dead_mu * radius * mass * G / 4.0)
    return pack(ReferenceKernelParams, p, radius=radius, lf=lf, lr=lr, torque_dead=torque_dead,
                xw=np.ascontiguousarray(xw, dtype=float),
                yw=np.ascontiguousarray(yw, dtype=float), **speed)


def new_reference_state(window: int) -> ReferenceState:
    """A fresh :class:`ReferenceState` (not started) with an ω history of ``window`` rows."""
    return ReferenceState(x=np.zeros(5), P=np.zeros((5, 5)), hist=np.zeros((window, 5)),
                          t_prev=np.zeros(1), started=np.zeros(1, dtype=np.bool_),
                          fx_prev=np.zeros(1), fy_prev=np.zeros(1), r_prev=np.zeros(1),
                          n_rejected=np.zeros(1, dtype=np.int64),
                          oldest=np.zeros(1, dtype=np.int64), wheel_v=np.zeros(4),
                          wheel_slip=np.zeros(4), wheel_sig=np.zeros(4), fy_var=np.zeros(1),
                          t_vy_rejected=np.zeros(1),
                          t_speed_rejected=np.zeros(1), alpha_demo=np.zeros(1),
                          t_vy_unverified=np.zeros(1), work=np.zeros((2, 5)))


@njit(**_JIT)
def copy_reference_state(dst: ReferenceState, src: ReferenceState) -> None:
    """``dst`` ← ``src``, array by array in place (same window)."""
    dst.x[:] = src.x
    dst.P[:, :] = src.P
    dst.hist[:, :] = src.hist
    dst.t_prev[:] = src.t_prev
    dst.started[:] = src.started
    dst.fx_prev[:] = src.fx_prev
    dst.fy_prev[:] = src.fy_prev
    dst.r_prev[:] = src.r_prev
    dst.n_rejected[:] = src.n_rejected
    dst.oldest[:] = src.oldest
    dst.wheel_v[:] = src.wheel_v
    dst.wheel_slip[:] = src.wheel_slip
    dst.wheel_sig[:] = src.wheel_sig
    dst.fy_var[:] = src.fy_var
    dst.t_vy_rejected[:] = src.t_vy_rejected
    dst.t_speed_rejected[:] = src.t_speed_rejected
    dst.alpha_demo[:] = src.alpha_demo
    dst.t_vy_unverified[:] = src.t_vy_unverified


@njit(**_JIT)
def _reference_rows(prm: ReferenceKernelParams, st: ReferenceState, start: int, stop: int,
                    t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                    axle_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                    fy_sd: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                    extra_v: np.ndarray, extra_var: np.ndarray, out_v: np.ndarray,
                    out_sig: np.ndarray, out_bias: np.ndarray, out_trust: np.ndarray) -> None:
    """Rows [start, stop) of :func:`reference_kernel`: the per-sample body of
    :func:`reference_step` and the loop of the batch kernel in one function. The arrays of
    ``st`` and ``prm`` are taken once per call: a NamedTuple's array field is a new
    reference (two atomic reference-count operations), and a call per sample with them
    made the batch kernel 1.5 times slower (and a call with the arrays unpacked, 2.5)."""
    (x, P, hist, t_prev, started, fx_prev, fy_prev, r_prev, n_rejected, oldest_row, wheel_v,
     wheel_slip, wheel_sig, fy_var, t_vy_rej, t_speed_rej, alpha_demo, t_unverified,
     work) = st
    xw, yw = prm.xw, prm.yw
    m = hist.shape[0]
    nx = x.shape[0]
    for k in range(start, stop):
        dt = t[k] - t_prev[0]
        if not started[0]:
            v0 = 0.0
            n_wheels = 0
            for i in range(4):
                if not np.isnan(omega[k, i]):
                    v0 += 0.25 * prm.radius * omega[k, i]
                    n_wheels += 1
            p_vx = 1.0
            if n_wheels == 0:
                # No wheel speeds: start from this sample's CG-speed measurement if any,
                # with a σ of 10 m/s so that the first one passes the gate.
                for j in range(extra_v.shape[1]):
                    if not np.isnan(extra_v[k, j]):
                        v0 = extra_v[k, j]
                        break
                p_vx = 100.0
            elif n_wheels < 4:
                v0 *= 4.0 / n_wheels
            x[:] = 0.0
            x[VX] = v0
            P[:, :] = 0.0
            P[VX, VX] = p_vx
            P[VY, VY] = 0.25
            P[BX, BX] = 0.25
            P[BY, BY] = 0.05**2
            P[BR, BR] = prm.gyro_bias_sd * prm.gyro_bias_sd
            fy_var[0] = 0.0
            t_vy_rej[0] = 0.0
            t_speed_rej[0] = 0.0
            alpha_demo[0] = 0.0
            t_unverified[0] = 0.0
            started[0] = True
            for j in range(m):
                hist[j, 0] = t[k]
                for i in range(4):
                    hist[j, 1 + i] = omega[k, i]
            oldest_row[0] = 0
        else:
            fxp, fyp = fx_prev[0], fy_prev[0]
            rp = r_prev[0] - x[BR]
            vx, vy = x[VX], x[VY]
            # Prediction (000 eq. (15) with the lateral equation and bias states):
            # v̇x = f_x − b_x + (r − b_r) v_y,  v̇y = f_y − b_y − (r − b_r) v_x  (inputs of the
            # previous sample). The gyro bias b_r enters v_y scaled by v_x, so unlike the
            # accelerometer bias b_y it changes with speed (0.002 rad/s × 25 m/s of speed
            # change = 0.05 m/s² of v̇_y error) and is observable as the speed changes.
            if prm.kin_fx:  # f_x is a speed's derivative: it already holds the r v_y term
                x[VX] = vx + dt * (fxp - x[BX])
            else:
                x[VX] = vx + dt * (fxp - x[BX] + rp * vy)
            x[VY] = vy + dt * (fyp - x[BY] - rp * vx)
            # Covariance P ← F P Fᵀ with the r-coupling of v_x and v_y in F (000 eq. (15)'s
            # Jacobian): F = I but for the rows
            #   v_x: ∂/∂v_y = dt (r − b_r), ∂/∂b_x = −dt, ∂/∂b_r = −dt v_y  (not where f_x is
            #        a speed's derivative, which holds r v_y already),
            #   v_y: ∂/∂v_x = −dt (r − b_r), ∂/∂b_y = −dt, ∂/∂b_r = dt v_x.
            # It was left out (two decoupled blocks) for fear that a gyro bias on a straight
            # road would make the v_y pseudo-measurements a spurious v_x measurement; kept out,
            # v_x followed a drifting v_y through r v_y and no speed fix corrected v_y (Revs:
            # β 1.95° with it out, 0.86° with it in; v_x 0.073 → 0.052 m/s).
            fxy = 0.0 if prm.kin_fx else dt * rp
            fxr = 0.0 if prm.kin_fx else -dt * vy
            fyx, fyr = -dt * rp, dt * vx
            # F P: rows v_x and v_y (from the old rows), the others unchanged.
            for j in range(nx):
                work[0, j] = P[VX, j] + fxy * P[VY, j] - dt * P[BX, j] + fxr * P[BR, j]
                work[1, j] = P[VY, j] + fyx * P[VX, j] - dt * P[BY, j] + fyr * P[BR, j]
            for j in range(nx):
                P[VX, j] = work[0, j]
                P[VY, j] = work[1, j]
            # (F P) Fᵀ: columns v_x and v_y likewise.
            for j in range(nx):
                work[0, j] = P[j, VX] + fxy * P[j, VY] - dt * P[j, BX] + fxr * P[j, BR]
                work[1, j] = P[j, VY] + fyx * P[j, VX] - dt * P[j, BY] + fyr * P[j, BR]
            for j in range(nx):
                P[j, VX] = work[0, j]
                P[j, VY] = work[1, j]
            P[VX, VX] += prm.q_vx * dt
            # v_y's process noise from the log's own f_y: its measured white noise (σ² T_s
            # per second) and its relative model error (roll gravity, scale), correlated
            # over τ_fy (2 τ (σ_s f_y)² per second).
            d_fy = f_y[k] - fyp
            if dt > 0:
                fy_var[0] += min(dt / prm.fy_noise_tau, 1.0) * (0.5 * d_fy * d_fy - fy_var[0])
            s_fy = np.hypot(prm.fy_scale_sd, fy_sd[k]) * fyp
            P[VY, VY] += (prm.q_vy + fy_var[0] * dt + 2.0 * prm.tau_fy * s_fy * s_fy) * dt
            P[BX, BX] += prm.q_bias * dt
            P[BY, BY] += prm.q_bias_y * dt
            P[BR, BR] += prm.q_gyro_bias * dt
        oldest = oldest_row[0]  # ring buffer: the oldest row is overwritten next
        span = t[k] - hist[oldest, 0]
        r_now = yaw_rate[k] - x[BR]
        # Wheel speeds mapped to the CG, trusted by their evidence of slip.
        accepted = 0
        available = 0
        r_w = prm.r_wheel
        sq_rw = np.sqrt(r_w)
        inflate_w = max(prm.tau_wheel / dt, 1.0) if dt > 0 else 1.0
        # First pass: each wheel's CG speed and its σ from the slip evidence, against the
        # predicted v_x; how many wheels agree with it within ``soft_gate`` σ.
        vx_pred = x[VX]
        p_pred = P[VX, VX]
        n_agree = 0
        for i in range(4):
            if np.isnan(omega[k, i]):  # no wheel speed: no measurement (a log without them)
                wheel_v[i] = np.nan
                wheel_sig[i] = np.inf
                wheel_slip[i] = 0.0
                continue
            available += 1
            d = delta[k, i]
            c, s = (np.cos(d), np.sin(d)) if d != 0.0 else (1.0, 0.0)
            vxw = vx_pred - r_now * yw[i]
            vyw = x[VY] + r_now * xw[i]
            vyt = -vxw * s + vyw * c
            v_meas = (prm.radius * omega[k, i] * c - vyt * s + r_now * yw[i]
                      - prm.slip_bias * mu_x[k, i] * abs(vx_pred))
            omega_dot = (omega[k, i] - hist[oldest, 1 + i]) / span if span > 0 else 0.0
            acc_err = max(abs(prm.radius * omega_dot - f_x[k] + x[BX]) - prm.acc_dead, 0.0)
            # The slip evidence: the expected slip's own error, ω̇ against a_x. Not the wheel's
            # sideways speed: a tire at a slip angle keeps its longitudinal slip (a free-rolling
            # one ≈ 0; the crossplant rear wheels −0.001 at 2° of slip angle), and v_yt comes
            # from v̂_y, whose error then de-weighted all four wheels in a turn (x06 CG v_x
            # 0.53 %, 0.075 % without it; with the term on driven and braked wheels only,
            # x07 0.031 → 0.054 %, campaign brake and accelerating turns worse by 0.05–0.07).
            sig = (sq_rw + prm.k_mu * abs(mu_x[k, i]) * abs(vx_pred) + prm.k_acc * acc_err)
            innov_pred = v_meas - vx_pred
            tq = torque[k, i]
            if ((tq > prm.torque_dead and innov_pred > 0)
                    or (tq < -prm.torque_dead and innov_pred < 0)):
                sig *= 1.0 + (innov_pred / prm.slip_sign) ** 2
            wheel_v[i] = v_meas
            wheel_sig[i] = sig
            wheel_slip[i] = abs(innov_pred) / max(abs(vx_pred), 1.0)
            if innov_pred * innov_pred <= prm.soft_gate * prm.soft_gate * (p_pred + sig * sig):
                n_agree += 1
        # Second pass: the updates. The slip part of σ is a persistent error (a slipping
        # wheel stays slipping), so it enters with the correlation-time inflation, like the
        # lateral model error; the gate uses the plain σ. A wheel beyond ``soft_gate`` σ
        # while another wheel agrees with v_x is the odd one out (a spinning wheel at the
        # turn of its oscillation shows no torque or ω̇ evidence for a moment): its excess
        # innovation enters as slip, with the same inflation.
        for i in range(4):
            if np.isnan(wheel_v[i]):
                out_trust[k, i] = np.inf
                continue
            sig = wheel_sig[i]
            slip_part = sig - sq_rw
            innov_0 = wheel_v[i] - vx_pred
            s_0 = prm.soft_gate * prm.soft_gate * (p_pred + sig * sig)
            if innov_0 * innov_0 > s_0 and n_agree > 0:
                soft = np.sqrt(max(innov_0 * innov_0 / (prm.soft_gate * prm.soft_gate)
                                   - p_pred, 0.0))
                slip_part = max(slip_part, soft - sq_rw)
            innov_pred = wheel_v[i] - x[VX]
            if innov_pred * innov_pred > prm.gate * prm.gate * (P[VX, VX] + sig * sig):
                res = np.nan
            else:
                res = direct_update(x, P, VX, wheel_v[i],
                                    r_w + slip_part * slip_part * inflate_w, np.inf, work)
            out_trust[k, i] = np.inf if np.isnan(res) else sig
            if not np.isnan(res):
                accepted += 1
        # Recovery: every wheel rejected although none shows evidence of slip means the
        # filter, not the wheels, has drifted. After ``window`` such samples, restart v_x
        # from the median wheel speed (an ESC unit's reference-speed reset).
        n_rejected[0] = n_rejected[0] + 1 if accepted == 0 and available > 0 else 0
        if n_rejected[0] >= m:
            x[VX] = np.median(wheel_v) if available == 4 else np.nanmedian(wheel_v)
            for j in range(nx):
                P[VX, j] = 0.0
                P[j, VX] = 0.0
            P[VX, VX] = r_w
            n_rejected[0] = 0
        # Extra CG-speed measurements (fusion with the corner-based estimators).
        n_extra = 0
        n_extra_ok = 0
        innov_extra = 0.0
        for j in range(extra_v.shape[1]):
            if not np.isnan(extra_v[k, j]):
                # A corner observer's error persists like a wheel's slip error: same inflation.
                n_extra += 1
                res = direct_update(x, P, VX, extra_v[k, j], extra_var[k, j] * inflate_w,
                                    prm.gate, work)
                if np.isnan(res):
                    innov_extra = extra_v[k, j] - x[VX]
                else:
                    n_extra_ok += 1
        # Without wheel speeds the CG-speed measurements are v_x's only anchor: rejected at
        # every sample for reacquire_s, the integral has drifted, not they (re-acquisition).
        if available == 0 and n_extra > 0:
            t_speed_rej[0] = t_speed_rej[0] + dt if n_extra_ok == 0 else 0.0
            if t_speed_rej[0] >= prm.reacquire_s:
                P[VX, VX] += innov_extra * innov_extra
                t_speed_rej[0] = 0.0
        # v_y from each axle's slip angle by the linear tire (front: v_y = v_x(α_f + δ) − l_f r,
        # rear: v_y = v_x α_r + l_r r). Its error grows with the slip angle (stiffness
        # uncertainty, k_rel) and with the sideslip acceleration |f_y − b_y − r v_x| (the
        # tires are off their linear range while the car slides, k_vy); innovations beyond
        # gate_vy σ are rejected: a saturated axle says nothing about v_y, and the
        # integration (its drift held by b_y, learnt while the tires were linear) carries on.
        # The sideslip acceleration beyond what the log's own f_y noise explains (2σ of
        # its measured white noise): vibration is no evidence of a slide.
        beta_acc = max(abs(f_y[k] - x[BY] - r_now * x[VX]) - 2.0 * np.sqrt(fy_var[0]), 0.0)
        d_f = 0.5 * (delta[k, 0] + delta[k, 1])
        # Both axles on the linear tire with the identified stiffness give the same v_y
        # (their difference is the kinematic L r/v_x − δ): a gap between them means one is
        # saturating or sliding, whatever the friction; both are then bounds (h_pair → 0).
        # On low μ this is the only sign: the linear slip angle stays small in a slide.
        lf, lr = prm.lf, prm.lr
        h_pair = 1.0
        if not (np.isnan(axle_slip[k, 0]) or np.isnan(axle_slip[k, 1])):
            gap = ((x[VX] * (axle_slip[k, 0] + d_f - axle_slip[k, 1]) - (lf + lr) * r_now)
                   / prm.pair_gap)
            h_pair = 1.0 / (1.0 + gap * gap)
        if prm.demo_ratio > 0.0:
            alpha_demo[0] *= np.exp(-dt / prm.demo_tau) if dt > 0 else 1.0
            for a in range(2):
                if not np.isnan(axle_slip[k, a]):
                    alpha_demo[0] = max(alpha_demo[0], abs(axle_slip[k, a]))
        below_demo = True
        n_lat = 0
        n_lat_ok = 0
        innov_lat = 0.0
        for a in range(2):
            alpha = axle_slip[k, a]
            if np.isnan(alpha):
                continue
            z = (x[VX] * (alpha + d_f) - lf * r_now if a == 0 else x[VX] * alpha + lr * r_now)
            # In the linear range (|α| below α_lin) the linear tire gives a value: tight σ,
            # short correlation, pulled on both sides; towards saturation (friction unknown)
            # only a bound: σ k_rel_sat |v_x α|, a second of correlation, one-sided, 3σ gate.
            # h blends the two by the slip angle itself.
            q = (alpha / prm.alpha_lin) ** 2
            if prm.demo_ratio > 0.0 and abs(alpha) >= prm.demo_ratio * max(alpha_demo[0],
                                                                           prm.alpha_lin):
                below_demo = False
            h = h_pair / (1.0 + q * q)
            sig = ((prm.k_rel_sat + h * (prm.k_rel - prm.k_rel_sat)) * abs(x[VX] * alpha)
                   + prm.k_vy * beta_acc)
            tau_a = prm.tau_vy_sat + h * (prm.tau_vy - prm.tau_vy_sat)
            inflate = max(tau_a / dt, 1.0) if dt > 0 else 1.0
            side = prm.side_vy_sat + h * (prm.side_vy - prm.side_vy_sat)
            # A wheel in longitudinal slip is in combined slip: its lateral force falls short
            # of the linear tire's, so the bound's one-sidedness sharpens with the axle's
            # larger slip ratio λ (wheel-speed innovation over speed): side/(1 + (λ/λ_c)²).
            lam = max(wheel_slip[2 * a], wheel_slip[2 * a + 1]) / prm.k_comb
            side /= 1.0 + lam * lam
            res = _lateral_update(x, P, z, alpha, prm.r_vy, sig, inflate, side,
                                  prm.gate_vy_sat + h * (prm.gate_vy - prm.gate_vy_sat), work)
            n_lat += 1
            if np.isnan(res):
                innov_lat = z - x[VY]
            else:
                n_lat_ok += 1
        # Re-acquisition: both axles rejected for reacquire_s while they agree with each
        # other (pair gap below pair_gap: the single-track kinematics hold, so the tires are
        # in their linear range) means v_y has left them (an integral that drifted, a wrong
        # roll or scale), not that they saturate: v_y's variance is raised to the squared
        # innovation, so the next pseudo-measurement passes its gate and pulls v_y back.
        # Axles that disagree (a slide: the linear slip angle under-states it) hold the
        # count; an accepted one clears it.
        t_unverified[0] = 0.0 if n_lat_ok > 0 else t_unverified[0] + max(dt, 0.0)
        if n_lat > 0:
            if n_lat_ok > 0:
                t_vy_rej[0] = 0.0
            elif h_pair >= 0.5 and below_demo:
                t_vy_rej[0] += dt
            if t_vy_rej[0] >= prm.reacquire_s:
                P[VY, VY] += innov_lat * innov_lat
                t_vy_rej[0] = 0.0
        # The biases are physically bounded (sensor bias plus a grade or bank of at most
        # ~5 %): a larger value means slip or a sliding car is being explained away as bias.
        x[BX] = min(max(x[BX], -prm.bias_max), prm.bias_max)
        x[BY] = min(max(x[BY], -prm.bias_y_max), prm.bias_y_max)
        # History for ω̇, and inputs held over the next interval.
        hist[oldest, 0] = t[k]
        for i in range(4):
            hist[oldest, 1 + i] = omega[k, i]
        oldest_row[0] = (oldest + 1) % m
        t_prev[0] = t[k]
        fx_prev[0] = f_x[k]
        fy_prev[0] = f_y[k]
        r_prev[0] = yaw_rate[k]
        out_v[k, 0] = x[VX]
        out_v[k, 1] = x[VY]
        out_sig[k, 0] = np.sqrt(max(P[VX, VX], 0.0))
        out_sig[k, 1] = np.sqrt(max(P[VY, VY], 0.0))
        out_bias[k, 0] = x[BX]
        out_bias[k, 1] = x[BY]
        out_bias[k, 2] = x[BR]
        out_bias[k, 3] = t_unverified[0]


@njit(**_JIT)
def reference_step(prm: ReferenceKernelParams, st: ReferenceState, k: int, t: np.ndarray,
                   omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                   axle_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                   fy_sd: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                   extra_v: np.ndarray, extra_var: np.ndarray, out_v: np.ndarray,
                   out_sig: np.ndarray, out_bias: np.ndarray, out_trust: np.ndarray) -> None:
    """Sample ``k`` of :func:`reference_kernel` (row ``k`` of its inputs and outputs), in
    place on ``st``; allocates nothing (but the median of the recovery)."""
    _reference_rows(prm, st, k, k + 1, t, omega, torque, mu_x, axle_slip, f_x, f_y, fy_sd,
                    yaw_rate, delta, extra_v, extra_var, out_v, out_sig, out_bias, out_trust)


@njit(**_JIT)
def reference_kernel(prm: ReferenceKernelParams, st: ReferenceState, t: np.ndarray,
                     omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                     axle_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                     fy_sd: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                     extra_v: np.ndarray, extra_var: np.ndarray, out_v: np.ndarray,
                     out_sig: np.ndarray, out_bias: np.ndarray, out_trust: np.ndarray) -> None:
    """Advance the reference filter over a chunk, in place on ``st``: :func:`reference_step`
    for each sample (the same body, with the loop inside it, see :func:`_reference_rows`).

    ``prm`` from :func:`reference_params`; ``st`` a :class:`ReferenceState`. Inputs (n rows):
    t (s), ω (n, 4) rad/s (NaN: no wheel speed), wheel torques (n, 4) N m, μ_x (n, 4),
    ``axle_slip`` (n, 2): front and rear axle slip angles from the lateral forces and the
    nominal cornering stiffness, rad (spec sign: atan(v_yt/v_xt)), NaN where unknown; f_x,
    f_y (m/s²) in the road plane, ``fy_sd`` (n,) the relative one-sigma of f_y that the
    attitude leaves (an identified roll gradient's; 0 where measured), yaw rate (rad/s),
    δ (n, 4) rad; ``extra_v``/``extra_var``
    (n, m2): extra CG-speed measurements (m/s) and variances ((m/s)²), NaN where absent.
    Outputs: out_v (n, 2) [v_x, v_y], out_sig (n, 2), out_bias (n, 4) [b_x, b_y, b_r, and the
    time since a v_y pseudo-measurement was last accepted, s], out_trust (n, 4) the standard
    deviation used per wheel (inf where rejected).
    """
    _reference_rows(prm, st, 0, t.shape[0], t, omega, torque, mu_x, axle_slip, f_x, f_y,
                    fy_sd, yaw_rate, delta, extra_v, extra_var, out_v, out_sig, out_bias,
                    out_trust)


class ReferenceFilter:
    """Stateful wrapper of :func:`reference_kernel` (``reset``, ``advance``).

    Args:
        radius: wheel radius R, m.
        lf, lr: CG to front / rear axle, m.
        xw, yw: corner positions from the CG (fl, fr, rl, rr), m.
        params: tuning.
        mass: vehicle mass, kg, for the load share of the torque dead zone (0: unknown, the
            N m floor alone).
    """

    def __init__(self, radius: float, lf: float, lr: float, xw: np.ndarray, yw: np.ndarray,
                 params: ReferenceParams | None = None, mass: float = 0.0) -> None:
        self.radius = radius
        self.lf = lf
        self.lr = lr
        self.xw = np.ascontiguousarray(xw, dtype=float)
        self.yw = np.ascontiguousarray(yw, dtype=float)
        self.params = params or ReferenceParams()
        geometry = (radius, lf, lr, self.xw, self.yw)
        self.kernel_params = reference_params(self.params, *geometry, mass=mass)
        """The kernel's parameters (f_x the IMU's specific force)."""
        self.kernel_params_speed = reference_params(self.params, *geometry, fx_from_speed=True,
                                                    mass=mass)
        """The kernel's parameters where f_x is a speed's derivative (``fx_from_speed``)."""
        self.reset()

    def reset(self) -> None:
        self.state = new_reference_state(self.params.window)

    def snapshot(self) -> ReferenceState:
        """A copy of the filter's state, for :meth:`restore`."""
        return ReferenceState(*(a.copy() for a in self.state))

    def restore(self, snap: tuple[np.ndarray, ...]) -> None:
        """Continue from a :meth:`snapshot` (of this filter or of one with the same params)."""
        copy_reference_state(self.state, ReferenceState(*snap))

    def advance(self, t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                axle_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray, yaw_rate: np.ndarray,
                delta: np.ndarray,
                extra_v: np.ndarray | None = None,
                extra_var: np.ndarray | None = None,
                fx_from_speed: bool = False,
                fy_sd: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Process a chunk; returns v (n, 2) [v_x, v_y] m/s, sigma (n, 2), bias (n, 4) [b_x, b_y]
        m/s², b_r rad/s and the time since v_y's last accepted pseudo-measurement (s),
        trust (n, 4).

        ``axle_slip`` (n, 2) holds the front and rear axle slip angles −F_y/C_y in rad (NaN
        where unknown); ``extra_v``/``extra_var`` (n, m) extra CG-speed measurements, m/s
        and (m/s)², NaN where absent. ``fx_from_speed``: ``f_x`` is the derivative of a
        speed (a log without ``ax``), i.e. v̇_x itself, not the specific force v̇_x − r v_y:
        the prediction leaves out r v_y, its process intensity is ``q_vx_speed``, and the
        slip-signed inflation is off
        (``slip_sign`` = ∞: a wheel reading below the integral while braked is no evidence of
        slip when the integral is the wheels' own, and inflating it would leave v_x to the
        integral's lag).
        """
        n = t.shape[0]
        if extra_v is None or extra_var is None:
            extra_v = np.full((n, 0), np.nan)
            extra_var = np.full((n, 0), np.nan)
        v = np.empty((n, 2))
        sig = np.empty((n, 2))
        bias = np.empty((n, 4))
        trust = np.empty((n, 4))
        prm = self.kernel_params_speed if fx_from_speed else self.kernel_params
        fy_sd = np.zeros(n) if fy_sd is None else np.ascontiguousarray(fy_sd, dtype=float)
        reference_kernel(prm, self.state, t, omega, torque, mu_x, np.ascontiguousarray(axle_slip),
                         f_x, f_y, fy_sd, yaw_rate, delta, np.ascontiguousarray(extra_v),
                         np.ascontiguousarray(extra_var), v, sig, bias, trust)
        return {"v": v, "sigma": sig, "bias": bias, "trust": trust}
