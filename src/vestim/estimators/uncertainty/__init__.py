"""One-sigma uncertainty of every estimated channel (issue 15), by first-order propagation.

The estimates are not changed: this stage only adds ``sigma_<channel>`` columns. One compiled
kernel, :func:`uncertainty_kernel`, turns the arrays the pipeline holds after its velocity
stage (:mod:`vestim.pipeline.rows`) into σ for the CG velocity (calibrated), the corner velocities in the
body and tire frames, the slip ratio and slip angle, the normal loads and the body angles.
Its only state is the online wheel-speed noise estimate (:func:`new_state`), carried between
chunks as the other kernels' states are, so ``run`` and ``step`` (the same kernel on n = 1
arrays) agree.

Error sources and their σ (SI; the coefficients are :class:`UncertaintyParams`):

* **CG velocity** (the reference filter's (v_x, v_y); its P is block diagonal between
  [v_x, b_x] and [v_y, b_y, b_r], so the 2×2 covariance of (v_x, v_y) is diagonal):
      σ_vx² = (k_Px σ_Px)² + (σ_vx0 + k_v |v_x| + τ_lat |a_x|)²,
      σ_vy² = (k_Py σ_Py)² + (σ_vy0 + k_α |v_x| α̂)² + d²,   α̂ = |a_y| / (g C̃_y),
      ḋ = k_d |a_y| − d / (τ_d (1 + (a_y/a_s)²)),
  σ_P the filter's √P. The filter inflates every wheel and lateral measurement by its
  correlation time (τ/T_s), which makes √P_vx 3–10× the actual v_x error in normal driving
  (our simulator and the crossplant logs alike), while it shrinks with the slip evidence as
  it should: k_Px = 0.1 scales it back. k_v |v_x| is the effective rolling radius's error
  against the vehicle file's (tyre wear, pressure, load: a scale error of the whole speed
  that no wheel measurement reveals without a speed reference); it dominates a real car's
  v_x error (the RAV4 log: 0.84 % of the speed without GNSS, 0.43 % with it) and is exactly
  0 on a simulated plant whose radius is the file's. σ_vx0 is the wheel-speed resolution,
  τ_lat |a_x| the wheel-speed latency (CAN frames at 50 Hz: up to 20 ms). d is the drift of
  the integrated v_y while the car corners (the lateral pseudo-measurements are then only
  bounds, and the errors of a_y − r v_x — roll's gravity leak, gyro bias × speed — are
  integrated): on our simulator and the crossplant logs |e_vy| grows through a sustained
  turn and is gone about a second after it; τ_d = 1 s and a_s = 1 m/s² are that recovery
  (the calibration gives k_d = 0: on the independent logs the α̂ term carries it).
  α̂ is the axle slip angle a linear tire with the online normalised cornering stiffness
  C̃_y (``cornering_stiffness``, 1/rad) needs for the lateral acceleration; the v_y
  pseudo-measurement v_x (α + δ) − l r is off by v_x δα, and δα/α, the relative error of
  the linear tire (stiffness uncertainty and saturation), is k_α. σ_vy0 is the v_y error
  that stays when the car drives straight (the a_y bias and the roll's gravity leak
  integrated between pseudo-measurements, the yaw-gyro bias × the axle lever arm). Where
  the filter accepts no v_y pseudo-measurement (validity reason 64, "v_y unverified") its
  P_vy grows with the integration and is raised to the squared innovation on
  re-acquisition, so σ_vy grows with the divergence through σ_Py (k_Py = 1 keeps it whole).
  k_Px, k_v, σ_vx0, k_Py, σ_vy0, k_α and k_d are calibrated on the independent logs (the
  crossplant x01–x12, the crossplant campaign seed 1 and the real logs:
  ``benchmarks/coverage_table.py --calibrate``, one set for every log); our own simulator
  (:data:`CALIBRATION_RUNS`) is kept for regression only.
* **Corner velocities** v_x,i = v_x − r y_i, v_y,i = v_y + r x_i (σ_vx, σ_vy independent,
  yaw-rate error σ_r: gyro noise and bias, :class:`vestim.sim.SensorModel`'s 0.003 and
  0.002 rad/s): σ²_vx,i = σ_vx² + y_i² σ_r², σ²_vy,i = σ_vy² + x_i² σ_r², covariance
  −x_i y_i σ_r² (carried into the tire frame).
* **Tire frame** v_xt = v_x,i c + v_y,i s, v_yt = −v_x,i s + v_y,i c (δ the steering angle):
  Jacobian in (v_x,i, v_y,i, δ), ∂/∂δ = (v_yt, −v_xt); σ_δ = σ_δ0 + k_δ |δ| on the steered
  front wheels (steering quantisation 0.1°/√12 and a 5 % steering-ratio / Ackermann
  uncertainty), 0 on the rear ones (the pipeline's rear δ is 0 by construction).
* **Slip angle** α = atan(v_yt/v_xt): ∂α/∂v_yt = v_xt/ρ², ∂α/∂v_xt = −v_yt/ρ² with
  ρ² = v_xt² + v_yt²; below ρ = v_min = 0.5 m/s (the estimate's own threshold: the slip
  angle is set to 0 there and says nothing) σ² = (σ²_vxt + σ²_vyt)/v_min²; capped at π/2.
  σ grows as 1/speed.
* **Slip ratio** s = (R ω − v_xt)/max(|R ω|, |v_xt|): driving (|R ω| ≥ |v_xt|) ∂s/∂v_xt =
  −1/(R ω), ∂s/∂ω = v_xt/(R ω²); braking ∂s/∂v_xt = −R ω/v_xt², ∂s/∂ω = R/v_xt; plus the
  effective radius (σ_R/R = k_radius = 0.2 %: a 1000 N load change on a 250 kN/m tire
  moves R_eff ≈ R − δ/3 by 1.3 mm of 330 mm, 0.4 % peak) and the wheel-speed noise σ_ω,
  estimated online per wheel from the second difference of ω (var(ω_k − 2ω_{k−1} + ω_{k−2}) = 6 σ_ω² for white
  noise; the true wheel's jerk adds < 0.01 rad/s at 200 Hz), an exponential average over
  ``tau_noise``. Below the estimate's 0.1 m/s the slip ratio is 0 and σ is 1 (no
  information).
* **Normal loads**: the load-transfer model's parameters that a vehicle file does not
  know (``vestim.estimators.force.normal``, static mode): the CG height h, the roll-centre
  height h_rc, the front roll-stiffness share s_f, the static weight split (l_f) and the
  mass (payload). With m f_x, m f_y, m f_z = Σ F_z the total loads,
      ∂F_z,i/∂h = ∓ m f_x/(2L) (front −, rear +) ∓ s_i m f_y / t_i (left −, right +),
      ∂F_z,i/∂h_rc = ∓ m f_y (l_o/L − s_i)/t_i, ∂F_z,i/∂s_f = ∓ ± m (h − h_rc) f_y/t_i,
      ∂F_z,i/∂l_f = ∓ [m f_z/(2L) ± m h_rc f_y/(L t_i)], ∂F_z,i/∂m = F_z,i/m,
  (s_i = s_f front, 1 − s_f rear; l_o = l_r front, l_f rear), added in quadrature with
  the priors σ_h = 0.05 m, σ_hrc = 0.05 m, σ_sf = 0.1, σ_lf = 0.02 L, σ_m = 3 % (the
  spread of those values over passenger cars of one class, and a passenger's 75 kg) and a
  floor m σ_az/4 for the a_z noise and road unevenness.
* **Roll and pitch**: the quasi-static roll c_φ a_y (c_φ = m(h − h_rc)/k_φ) known to
  k_att = 30 % (roll stiffness and heights of a vehicle file are assumed), plus the tilt
  the accelerometer bias and road bank show, σ_att0 = 0.05 m/s² / g.

Every σ is finite and ≥ 0 where its inputs are finite; NaN inputs (a log without wheel
speeds: NaN slip ratio; a velocity method with no filter σ) give NaN σ for what depends
on them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
from numba import njit

from vestim.constants import CORNERS, G
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import corner_positions
from vestim.params import check_ranges, pack

CALIBRATION_RUNS: tuple[tuple[str, str, int], ...] = tuple(
    (veh, man, 0)
    for veh in ("hashemi_suv", "compact_car")
    for man in ("accel_brake", "ait_dry", "step_steer", "launch_split_mu", "dlc_snow", "lc_wet",
                "bit_slippery", "split_mu_brake", "oval", "ait_slippery"))
"""(vehicle, maneuver, seed) of our own simulator's runs: regression only (the tests check the
coverage on seed 1); the coefficients are calibrated on the independent logs."""

PER_CORNER: tuple[str, ...] = ("vx", "vy", "vxt", "vyt", "slip_ratio", "slip_angle", "fz")
"""Per-corner channels given a σ, in the order of the kernel's output blocks."""

OUTPUT_NAMES: tuple[str, ...] = (
    "sigma_vx", "sigma_vy",
    *(f"sigma_{q}_{c}" for q in PER_CORNER for c in CORNERS),
    "sigma_roll", "sigma_pitch")
"""Columns of the kernel's ``out`` (n, 32), in order."""

N_OUT = len(OUTPUT_NAMES)


@dataclass(frozen=True)
class UncertaintyParams:
    """Coefficients of the σ models (SI; see the module docstring for each one's origin).

    Attributes:
        k_filter_vx: scale on the reference filter's √P_vx, which its τ/T_s inflation of the
            wheel measurements makes 3–10× the actual v_x error (1 before issue 30: σ_vx up
            to 16× the RMSE on the crossplant logs).
        k_filter_vy: scale on √P_vy (1: it carries the growth where v_y is unverified).
        sigma_vx0: floor of the v_x model error, m/s (wheel-speed resolution).
        k_speed: v_x error per m/s of speed, 1: the effective rolling radius's relative
            error against the vehicle file (0 before issue 30, fitted on our simulator whose
            radius is exact; the RAV4 log's v_x error is 0.84 % of its speed).
        k_radius: relative effective-radius uncertainty in the slip ratio, 1.
        sigma_vy0: floor of the v_y model error, m/s (a_y bias and roll leak integrated
            between pseudo-measurements, yaw-gyro bias × the axle lever arm; 0.003 before
            issue 30, which left σ_vy 2.5× short of the RAV4's v_y error).
        tau_latency: wheel-speed latency, s (CAN wheel-speed frames at 50 Hz are up to
            20 ms old): the v_x error τ |a_x| in acceleration and braking.
        k_alpha: relative error of the linear tire's slip angle, 1 (0 before issue 30).
        k_drift: growth of the v_y drift per m/s² of |a_y|, (m/s)/s per m/s² (0.02 before
            issue 30, fitted on our simulator; 0 on the independent logs, where k_alpha's
            term carries the cornering error).
        tau_drift: time in which the v_y drift decays once the car drives straight, s.
        a_straight: |a_y| below which the car counts as driving straight (the drift's
            decay is weighted by 1/(1 + (a_y/a_straight)²)), m/s².
        sigma_yaw_rate: yaw-rate error, rad/s (gyro noise 0.003 and bias 0.002 in quadrature).
        sigma_delta0: steering-angle floor, rad (0.1° quantisation / √12).
        k_delta: relative steering-angle error (steering ratio and Ackermann), 1.
        v_min: speed below which the slip angle is 0 and its σ capped at π/2, m/s.
        v_min_slip: speed below which the slip ratio is 0 and its σ 1, m/s.
        sigma_omega_min: floor of the wheel-speed noise estimate, rad/s.
        tau_noise: averaging time of the wheel-speed noise estimate, s.
        sigma_cg_height: σ of the CG height, m.
        sigma_roll_center: σ of the roll-centre height, m.
        sigma_roll_share: σ of the front roll-stiffness share, 1.
        sigma_lf_rel: σ of l_f as a share of the wheelbase, 1.
        sigma_mass_rel: relative σ of the mass, 1.
        sigma_az: a_z noise and road unevenness, m/s² (floor of σ_Fz: m σ_az / 4).
        k_attitude: relative σ of the quasi-static roll and pitch gradients, 1.
        sigma_attitude0: floor of σ_roll and σ_pitch, rad (accelerometer bias / g).
    """

    k_filter_vx: float = 0.1
    k_filter_vy: float = 1.0
    sigma_vx0: float = 0.01
    k_speed: float = 0.004
    k_radius: float = 0.002
    tau_latency: float = 0.02
    sigma_vy0: float = 0.02
    k_alpha: float = 0.3
    k_drift: float = 0.0
    tau_drift: float = 1.0
    a_straight: float = 1.0
    sigma_yaw_rate: float = 0.0036
    sigma_delta0: float = 0.0005
    k_delta: float = 0.05
    v_min: float = 0.5
    v_min_slip: float = 0.1
    sigma_omega_min: float = 0.01
    tau_noise: float = 1.0
    sigma_cg_height: float = 0.05
    sigma_roll_center: float = 0.05
    sigma_roll_share: float = 0.1
    sigma_lf_rel: float = 0.02
    sigma_mass_rel: float = 0.03
    sigma_az: float = 0.05
    k_attitude: float = 0.3
    sigma_attitude0: float = 0.005

    @classmethod
    def filter_only(cls) -> UncertaintyParams:
        """σ_vx, σ_vy as the reference filter's own √P (no model-error terms, no scaling): the
        "before" that ``benchmarks/coverage_table.py`` calibrates post hoc."""
        return cls(k_filter_vx=1.0, k_filter_vy=1.0, sigma_vx0=0.0, k_speed=0.0,
                   tau_latency=0.0, sigma_vy0=0.0, k_alpha=0.0, k_drift=0.0)

    def __post_init__(self) -> None:
        check_ranges(self, "uncertainty", positive=("v_min", "v_min_slip", "tau_noise"),
                     nonnegative=(f.name for f in fields(self)), finite=True)


class UncertaintyKernelParams(NamedTuple):
    """:func:`uncertainty_step`'s parameters: the vehicle's geometry (corner positions
    ``x_*``, ``y_*`` from the CG, m; wheel radius, m; mass, kg; wheelbase, ``lf``, ``lr``,
    CG and roll-centre heights, tracks, m; the front roll-stiffness share, 1; the
    quasi-static roll and pitch gradients ``c_roll``, ``c_pitch``, rad per m/s²), then the
    :class:`UncertaintyParams` fields."""

    x_fl: float
    x_fr: float
    x_rl: float
    x_rr: float
    y_fl: float
    y_fr: float
    y_rl: float
    y_rr: float
    wheel_radius: float
    mass: float
    wheelbase: float
    lf: float
    lr: float
    cg_height: float
    roll_center_height: float
    roll_share_front: float
    track_f: float
    track_r: float
    c_roll: float
    c_pitch: float
    k_filter_vx: float
    k_filter_vy: float
    sigma_vx0: float
    k_speed: float
    k_radius: float
    tau_latency: float
    sigma_vy0: float
    k_alpha: float
    k_drift: float
    tau_drift: float
    a_straight: float
    sigma_yaw_rate: float
    sigma_delta0: float
    k_delta: float
    v_min: float
    v_min_slip: float
    sigma_omega_min: float
    tau_noise: float
    sigma_cg_height: float
    sigma_roll_center: float
    sigma_roll_share: float
    sigma_lf_rel: float
    sigma_mass_rel: float
    sigma_az: float
    k_attitude: float
    sigma_attitude0: float


class UncertaintyState(NamedTuple):
    """:func:`uncertainty_step`'s state: ``omega_1`` and ``omega_2`` (4,) the wheel speeds
    of the previous two samples (rad/s), ``noise_var`` (4,) the wheel-speed noise variance
    ((rad/s)²), ``t_last`` (1,) the time of the last sample (s) (all NaN until filled) and
    ``drift`` (1,) the v_y drift d (m/s, 0 at the start)."""

    omega_1: np.ndarray
    omega_2: np.ndarray
    noise_var: np.ndarray
    t_last: np.ndarray
    drift: np.ndarray


def uncertainty_params(vehicle: Vehicle,
                       params: UncertaintyParams | None = None) -> UncertaintyKernelParams:
    """:func:`uncertainty_step`'s parameters: the vehicle's geometry and the validated
    coefficients ``params`` (default :class:`UncertaintyParams`)."""
    p = params or UncertaintyParams()
    b, s = vehicle.body, vehicle.suspension
    xw, yw = corner_positions(vehicle)
    c_roll = b.mass * (b.cg_height - b.roll_center_height) / s.roll_stiffness
    c_pitch = b.mass * (b.cg_height - s.pitch_center_height) / s.pitch_stiffness
    corners = {f"{q}_{c}": v for q, vals in (("x", xw), ("y", yw))
               for c, v in zip(CORNERS, vals, strict=True)}
    return pack(UncertaintyKernelParams, p, **corners, wheel_radius=b.wheel_radius,
                mass=b.mass, wheelbase=b.wheelbase, lf=b.lf, lr=b.lr, cg_height=b.cg_height,
                roll_center_height=b.roll_center_height,
                roll_share_front=s.roll_stiffness_front_share, track_f=b.track_f,
                track_r=b.track_r, c_roll=abs(c_roll), c_pitch=abs(c_pitch))


def new_state() -> UncertaintyState:
    """A fresh :class:`UncertaintyState`."""
    return UncertaintyState(np.full(4, np.nan), np.full(4, np.nan), np.full(4, np.nan),
                            np.full(1, np.nan), np.zeros(1))


@njit(cache=True, error_model="numpy")
def _corner(i: int, fl: float, fr: float, rl: float, rr: float) -> float:
    """Corner ``i``'s value of (fl, fr, rl, rr)."""
    return fl if i == 0 else fr if i == 1 else rl if i == 2 else rr


@njit(cache=True, error_model="numpy", inline="always")
def uncertainty_step(p: UncertaintyKernelParams, s: UncertaintyState, t: float, vx: float,
                     sigma_vx: float, sigma_vy: float, delta: np.ndarray, omega: np.ndarray,
                     ax: float, ay: float, fz: np.ndarray, vxt: np.ndarray, vyt: np.ndarray,
                     slip_ratio: np.ndarray, cornering_stiffness: float,
                     out: np.ndarray) -> None:
    """σ of every channel of one sample at time ``t`` (s), written into ``out``
    (:data:`N_OUT`,) in the order of :data:`OUTPUT_NAMES`; ``s`` is advanced.

    Inputs: the CG ``vx`` (m/s) and the filter's ``sigma_vx``, ``sigma_vy`` (m/s), per
    corner (4,) the steering angle ``delta`` (rad), wheel speeds ``omega`` (rad/s), normal
    loads ``fz`` (N), tire-frame corner velocities ``vxt``, ``vyt`` (m/s) and
    ``slip_ratio`` (NaN: no wheel speeds); the IMU ``ax``, ``ay`` (m/s²) and the
    normalised ``cornering_stiffness`` C_y/ΣF_z (1/rad). See the module docstring.
    """
    # Wheel-speed noise from the second difference (white noise: variance 6 σ²).
    dt = t - s.t_last[0]
    w_avg = 1.0 if np.isnan(dt) else min(max(dt, 0.0) / p.tau_noise, 1.0)
    for i in range(4):
        om = omega[i]
        if not (np.isnan(s.omega_1[i]) or np.isnan(s.omega_2[i]) or np.isnan(om)):
            d2 = om - 2.0 * s.omega_1[i] + s.omega_2[i]
            var = d2 * d2 / 6.0
            if np.isnan(s.noise_var[i]):
                s.noise_var[i] = var
            else:
                s.noise_var[i] += w_avg * (var - s.noise_var[i])
        s.omega_2[i] = s.omega_1[i]
        s.omega_1[i] = om
    s.t_last[0] = t
    # v_y drift: grows with |a_y| while cornering, decays when driving straight.
    step = 0.0 if np.isnan(dt) else max(dt, 0.0)
    a_rel = ay / p.a_straight
    decay = step / p.tau_drift / (1.0 + a_rel * a_rel)
    s.drift[0] = (s.drift[0] + step * p.k_drift * abs(ay)) / (1.0 + decay)
    drift = s.drift[0]
    # CG velocity: the filter's σ (scaled) and the model error of the operating point.
    m_vx = p.sigma_vx0 + p.k_speed * abs(vx) + p.tau_latency * abs(ax)
    sx2 = (p.k_filter_vx * sigma_vx) ** 2 + m_vx * m_vx
    cy = cornering_stiffness
    alpha_hat = abs(ay) / (G * cy) if cy > 0.0 else 0.0
    m_vy = p.sigma_vy0 + p.k_alpha * abs(vx) * alpha_hat
    sy2 = (p.k_filter_vy * sigma_vy) ** 2 + m_vy * m_vy + drift * drift
    out[0] = np.sqrt(sx2)
    out[1] = np.sqrt(sy2)
    sr2 = p.sigma_yaw_rate * p.sigma_yaw_rate
    m_fz = 0.0
    for i in range(4):
        m_fz += fz[i]
    radius, mass, wb = p.wheel_radius, p.mass, p.wheelbase
    h, h_rc, sf = p.cg_height, p.roll_center_height, p.roll_share_front
    for i in range(4):
        xi = _corner(i, p.x_fl, p.x_fr, p.x_rl, p.x_rr)
        yi = _corner(i, p.y_fl, p.y_fr, p.y_rl, p.y_rr)
        # Corner velocities (body frame): covariance of (v_x,i, v_y,i).
        pxx = sx2 + yi * yi * sr2
        pyy = sy2 + xi * xi * sr2
        pxy = -xi * yi * sr2
        out[2 + i] = np.sqrt(pxx)
        out[6 + i] = np.sqrt(pyy)
        # Tire frame: rotation by δ plus the steering-angle error.
        d = delta[i]
        c, sn = np.cos(d), np.sin(d)
        sd = p.sigma_delta0 + p.k_delta * abs(d) if i < 2 else 0.0  # rear wheels not steered
        sd2 = sd * sd
        ut, wt = vxt[i], vyt[i]
        qxx = c * c * pxx + 2.0 * c * sn * pxy + sn * sn * pyy + wt * wt * sd2
        qyy = sn * sn * pxx - 2.0 * c * sn * pxy + c * c * pyy + ut * ut * sd2
        qxy = (-c * sn * pxx + (c * c - sn * sn) * pxy + c * sn * pyy) - ut * wt * sd2
        out[10 + i] = np.sqrt(max(qxx, 0.0))
        out[14 + i] = np.sqrt(max(qyy, 0.0))
        # Slip ratio.
        om = omega[i]
        rw = radius * om
        s_om = (p.sigma_omega_min if np.isnan(s.noise_var[i])
                else max(np.sqrt(s.noise_var[i]), p.sigma_omega_min))
        if np.isnan(slip_ratio[i]):
            out[18 + i] = np.nan
        elif max(abs(rw), abs(ut)) <= p.v_min_slip:
            out[18 + i] = 1.0
        elif abs(rw) >= abs(ut):  # driving: s = 1 − v_xt/(R ω)
            g_u = -1.0 / rw
            g_w = ut / (rw * om)
            g_rel = ut / rw  # R error: ∂s/∂R · R
            var = g_u * g_u * qxx + g_w * g_w * s_om * s_om + (g_rel * p.k_radius) ** 2
            out[18 + i] = min(np.sqrt(var), 1.0)
        else:  # braking: s = R ω/v_xt − 1
            g_u = -rw / (ut * ut)
            g_w = radius / ut
            g_rel = rw / ut
            var = g_u * g_u * qxx + g_w * g_w * s_om * s_om + (g_rel * p.k_radius) ** 2
            out[18 + i] = min(np.sqrt(var), 1.0)
        # Slip angle.
        rho2 = ut * ut + wt * wt
        if rho2 >= p.v_min * p.v_min:
            a_u, a_w = -wt / rho2, ut / rho2
            var = a_u * a_u * qxx + 2.0 * a_u * a_w * qxy + a_w * a_w * qyy
        else:  # the estimate is 0 here: any direction of the velocity error counts
            var = (qxx + qyy) / (p.v_min * p.v_min)
        out[22 + i] = min(np.sqrt(max(var, 0.0)), 0.5 * np.pi)
        # Normal load: the load-transfer parameters' uncertainty.
        front = i < 2
        side = -1.0 if i % 2 == 0 else 1.0  # F_z,left = ½F_z,axle − ΔF, right + ΔF
        tr = p.track_f if front else p.track_r
        share = sf if front else 1.0 - sf
        l_other = p.lr if front else p.lf
        sgn_lon = -1.0 if front else 1.0
        mfx, mfy = mass * ax, mass * ay
        d_h = sgn_lon * mfx / (2.0 * wb) + side * share * mfy / tr
        d_hrc = side * mfy * (l_other / wb - share) / tr
        d_sf = side * (1.0 if front else -1.0) * (h - h_rc) * mfy / tr
        # l_f moves the static split and the roll-centre share l_o/L of the lateral
        # transfer (l_r = L − l_f).
        d_lf = sgn_lon * (m_fz / (2.0 * wb) + side * mfy * h_rc / (wb * tr))
        var = ((d_h * p.sigma_cg_height) ** 2 + (d_hrc * p.sigma_roll_center) ** 2
               + (d_sf * p.sigma_roll_share) ** 2 + (d_lf * p.sigma_lf_rel * wb) ** 2
               + (fz[i] * p.sigma_mass_rel) ** 2 + (0.25 * mass * p.sigma_az) ** 2)
        out[26 + i] = np.sqrt(var)
    s_att0, k_att = p.sigma_attitude0, p.k_attitude
    out[30] = np.sqrt(s_att0 * s_att0 + (k_att * p.c_roll * ay) ** 2)
    out[31] = np.sqrt(s_att0 * s_att0 + (k_att * p.c_pitch * ax) ** 2)


@njit(cache=True, error_model="numpy")
def uncertainty_kernel(p: UncertaintyKernelParams, s: UncertaintyState, t: np.ndarray,
                       v: np.ndarray, sigma_v: np.ndarray, delta: np.ndarray,
                       omega: np.ndarray, ax: np.ndarray, ay: np.ndarray, fz: np.ndarray,
                       vxt: np.ndarray, vyt: np.ndarray, slip_ratio: np.ndarray,
                       cornering_stiffness: np.ndarray, out: np.ndarray) -> None:
    """:func:`uncertainty_step` over a chunk, into ``out`` (n, :data:`N_OUT`); ``s``
    (:func:`new_state`) is advanced in place.

    Inputs (n samples, C-contiguous): t (s), v (n, 2) the CG velocity and sigma_v (n, 2)
    the filter's σ (m/s), delta (n, 4) steering angle (rad), omega (n, 4) wheel speeds
    (rad/s), ax, ay the IMU accelerations (m/s²), fz (n, 4) normal loads (N), vxt, vyt
    (n, 4) tire-frame corner velocities (m/s), slip_ratio (n, 4) (NaN: no wheel speeds),
    cornering_stiffness the normalised C_y/ΣF_z (1/rad); ``p`` from
    :func:`uncertainty_params`.
    """
    for k in range(t.shape[0]):
        uncertainty_step(p, s, t[k], v[k, 0], sigma_v[k, 0], sigma_v[k, 1], delta[k],
                         omega[k], ax[k], ay[k], fz[k], vxt[k], vyt[k], slip_ratio[k],
                         cornering_stiffness[k], out[k])


def uncertainty(t: np.ndarray, v: np.ndarray, sigma_v: np.ndarray, delta: np.ndarray,
                omega: np.ndarray, ax: np.ndarray, ay: np.ndarray, fz: np.ndarray,
                vxt: np.ndarray, vyt: np.ndarray, slip_ratio: np.ndarray,
                cornering_stiffness: np.ndarray, p: UncertaintyKernelParams,
                state: UncertaintyState | None = None) -> dict[str, np.ndarray]:
    """:func:`uncertainty_kernel` on a chunk; returns ``{name: (n,) array}`` for every name of
    :data:`OUTPUT_NAMES` (``state``, if given, is advanced in place; else a fresh one).

    Raises:
        ValueError: an array whose length differs from ``t``'s.
        TypeError: ``p`` is not an :class:`UncertaintyKernelParams`.
    """
    n = t.shape[0]
    arrays = [np.ascontiguousarray(a, dtype=float) for a in
              (t, v, sigma_v, delta, omega, ax, ay, fz, vxt, vyt, slip_ratio,
               cornering_stiffness)]
    names = ("t", "v", "sigma_v", "delta", "omega", "ax", "ay", "fz", "vxt", "vyt",
             "slip_ratio", "cornering_stiffness")
    widths = (1, 2, 2, 4, 4, 1, 1, 4, 4, 4, 4, 1)
    for name, a, w in zip(names, arrays, widths, strict=True):
        shape = (n,) if w == 1 else (n, w)
        if a.shape != shape:
            raise ValueError(f"uncertainty input {name!r} has shape {a.shape}; expected {shape}")
    if not isinstance(p, UncertaintyKernelParams):
        raise TypeError(f"uncertainty p is a {type(p).__name__}; expected the "
                        "UncertaintyKernelParams of uncertainty_params(vehicle)")
    st = new_state() if state is None else state
    out = np.empty((n, N_OUT))
    (t_, v_, sv, d_, om, ax_, ay_, fz_, vxt_, vyt_, sl, cy) = arrays
    uncertainty_kernel(p, st, t_, v_, sv, d_, om, ax_, ay_, fz_, vxt_, vyt_, sl, cy, out)
    return {name: out[:, j] for j, name in enumerate(OUTPUT_NAMES)}
