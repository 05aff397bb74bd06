"""Body attitude and normal loads per corner, without road friction.

Attitude (000 Sec. II-B after Rehm): the body roll φ and pitch θ relative to
the road follow the measured rates, corrected toward their quasi-static values
with gains L_φ, L_θ (a complementary filter: rate at high frequency, load
balance at low frequency):
    φ̂̇ = p_m + L_φ (φ_ss − φ̂),   φ_ss = m (h − h_rc) a_y / k_φ,
    θ̂̇ = q_m + L_θ (θ_ss − θ̂),   θ_ss = −m (h − h_pc) a_x / k_θ,
where a_x, a_y are the IMU readings (the pendulum term of the roll/pitch
balance cancels the IMU's own tilt to first order, so no further correction
is needed). Without roll/pitch rate channels the quasi-static angles are used
(φ = φ_ss, θ = θ_ss sample by sample): what is lost is the suspension's response
to the load change — the lag and overshoot of the ~1.5 Hz roll and pitch modes —
so the angles and the elastic load transfer lead the true ones in transients and
agree in steady state. Without ``az`` see :func:`vestim.models.kinematics.level_road_az`.

Normal loads (our derivation; 000 eq. (13)–(14), 001 eq. (14)–(17) compared in
:func:`normal_loads_paper`): rotate the IMU specific force back to the road
plane with the body angles (f_x = a_x cos θ + a_z sin θ, f_z = a_z cos θ − a_x sin θ,
f_y = a_y cos φ − a_z sin φ; the spec's roll sign, left side up, is the
opposite of 001 eq. (16)'s) — road grade and bank need no estimate, because the
tires carry the specific force whatever its origin — then

    F_zf = m (l_r f_z − h f_x)/L,  F_zr = m (l_f f_z + h f_x)/L          (001 eq. (15))
    ΔF_f = [m (l_r/L) h_rc f_y + s_f M_el]/t_f,  ΔF_r = [m (l_f/L) h_rc f_y + (1 − s_f) M_el]/t_r
    F_z,fl = F_zf/2 − ΔF_f,  F_z,fr = F_zf/2 + ΔF_f  (rear alike),

with the elastic roll moment M_el carried by the springs: quasi-static
M_el = m (h − h_rc)(f_y + f_z sin φ) (``mode="static"``), or from the
suspension states M_el = k_φ φ̂ + c_φ p_m (``mode="dynamic"``; the pitch
transfer likewise uses k_θ θ̂ + c_θ q_m). s_f is the front share of roll
stiffness ([suspension] of the vehicle file). Two corrections to the printed
eq. (14) of 000 / (17) of 001: (i) the axle load F_zi is used directly, whereas
m_i ā_φz with m_i = F_zi/g counts the vertical acceleration twice; (ii) the
roll term is the sprung CG's lateral shift (h − h_rc) sin φ, not h_rc sin φ.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.estimators.registry import register, registered
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import euler_rates, middle_wheel_speed
from vestim.params import pack

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

register("normal", "static", "load transfer with the quasi-static elastic roll moment "
         "m (h − h_rc)(f_y + f_z sin φ)", default=True,
         cite="001 eq. (15) (our corrected form of 000 eq. (14), 001 eq. (17))",
         tables=("force_params",), needs_wheel_speeds=False)
register("normal", "dynamic", "load transfer with the roll moment of the suspension states "
         "k_φ φ̂ + c_φ p", cite="001 eq. (15)–(17), 000 Sec. II-B",
         tables=("force_params",), needs_wheel_speeds=False)
_REGISTERED = registered("normal")
MODES: tuple[str, ...] = tuple(_REGISTERED)
"""The normal-load models' names, in the registry's order."""
STATIC, DYNAMIC = (_REGISTERED[name].code for name in ("static", "dynamic"))
"""The normal-load models' registry codes."""


class AttitudeKernelParams(NamedTuple):
    """Parameters of :func:`attitude_kernel` (see there), made by :func:`attitude_params`."""

    roll_tau: float  # τ_φ, s
    pitch_gain: float  # L_θ, 1/s
    c_roll: float  # quasi-static roll per a_y, rad per m/s²
    c_pitch: float  # quasi-static pitch per a_x, rad per m/s²
    radius: float  # R, m
    rate_filter_hz: float  # f_acc, Hz
    undriven_axle: int  # 0 front, 1 rear, −1 none (four driven)
    roll_slide: float  # e_φ, rad
    roll_gain: float  # L_φ, 1/s (0: no stated [suspension])
    roll_bias_tau: float  # τ_b, s
    roll_identify: bool  # identify the roll gradient online (no roll rate, no stated one)
    roll_gradient_prior: float  # k₀, rad per m/s²
    roll_gradient_sd: float  # σ_k, rad per m/s²
    roll_id_tau: float  # forgetting time, s
    roll_id_noise: float  # σ_e, rad
    gravity: float  # 1: the accelerometers read the attitude's gravity, 0: gravity-free (INS)


class AttitudeState(NamedTuple):
    """State of :func:`attitude_kernel` (in place); each field a 1-element array,
    :func:`new_attitude_state` makes a fresh one.

    Attributes:
        roll, pitch: φ̂, θ̂, rad.
        t_prev: time of the previous sample, s.
        started: 1.0 once the first sample started the filter.
        p_lp, p_acc: the roll rate's differentiator: p̄ (rad/s) and ṗ̄ (rad/s²).
        q_lp, q_acc: the pitch rate's: q̄ (rad/s) and q̇̄ (rad/s²).
        roll_bias: b̂_p, the roll gyro's bias, rad/s.
        sxx, sx, s1, sxe, se: the roll-gradient regression's forgotten sums [Σx², Σx, Σ1,
            Σx e, Σe] (:func:`_roll_gradient`).
    """

    roll: np.ndarray
    pitch: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    p_lp: np.ndarray
    p_acc: np.ndarray
    q_lp: np.ndarray
    q_acc: np.ndarray
    roll_bias: np.ndarray
    sxx: np.ndarray
    sx: np.ndarray
    s1: np.ndarray
    sxe: np.ndarray
    se: np.ndarray


def new_attitude_state() -> AttitudeState:
    """A fresh :class:`AttitudeState` (the next sample starts the filter)."""
    return AttitudeState(*(np.zeros(1) for _ in AttitudeState._fields))


ROLL_ID_CORRELATION = 0.5
"""Correlation time of the sideslip acceleration in the roll-gradient regression, s."""
ROLL_GRADIENT_RANGE = (-0.01, 0.03)
"""Bounds of the identified roll gradient, rad per m/s² (−5.6 to 17°/g: an accelerometer's
scale error either way, and the softest suspension)."""
ROLL_BIAS_SD = 0.03
"""Prior one-sigma of the regression's offset, rad (0.3 m/s²: accelerometer and yaw-gyro
bias × speed, a bank)."""


def attitude_params(config: Any, c_roll: float, c_pitch: float, radius: float,
                    drivetrain: str, suspension_given: bool,
                    roll_known: bool = True) -> AttitudeKernelParams:
    """:class:`AttitudeKernelParams` from the force stage's config (its ``roll_tau``,
    ``pitch_gain``, ``rate_filter_hz``, ``roll_slide``, ``roll_gain``, ``roll_bias_tau`` and
    the roll-gradient identification's ``roll_gradient_prior``, ``roll_gradient_sd``,
    ``roll_id_tau``, ``roll_id_noise``) and the vehicle's values; L_φ only with a stated
    ``[suspension]``; the roll gradient is identified (without a roll rate) unless
    ``roll_known`` (a stated suspension or a calibrated gradient)."""
    return pack(AttitudeKernelParams, config, c_roll=c_roll, c_pitch=c_pitch, radius=radius,
                undriven_axle={"fwd": 1, "rwd": 0}.get(drivetrain, -1),
                roll_gain=config.roll_gain if suspension_given else 0.0,
                roll_identify=not roll_known,
                gravity=0.0 if config.accelerometer == "gravity_free" else 1.0)


@njit(**_JIT)
def _roll_gradient(prm: AttitudeKernelParams, state: AttitudeState, dt: float, ay: float,
                   r: float, v: float) -> None:
    """One sample of the online roll gradient k (rad per m/s²; :func:`roll_gradient_estimate`
    solves for it), ``state.sxx`` … ``se`` the forgotten sums [Σx², Σx, Σ1, Σx e, Σe] of the regression
    e = k x + b.

    e = (a_y − r v)/g is the tilt the lateral specific force shows beyond the centripetal
    acceleration x = r v: a body-fixed accelerometer in a car that rolls φ = k a_y reads
    g sin φ ≈ g k a_y of gravity there, an INS's gravity-free output none (k ≈ 0), and an
    accelerometer whose scale is off by s − 1 reads like k = (s − 1)/g. The regressor is
    r v, not a_y: the accelerometer's noise (up to 4 m/s² of vibration) would be on both
    sides of the regression and bias k by σ²/var(a_y) (to the 17°/g bound on the vibrating
    campaign logs). The sideslip acceleration v̇_y/g is the regression's noise (σ_e,
    correlated over 0.5 s: it averages out over turns both ways); b takes the
    accelerometer bias, the yaw-gyro bias × speed and a bank. Gaussian priors k₀ ± σ_k and
    0 ± 0.03 rad, forgetting time τ; k is clipped to :data:`ROLL_GRADIENT_RANGE`. No speed
    (NaN v): the sums are only forgotten.
    """
    lam = np.exp(-dt / prm.roll_id_tau)
    state.sxx[0] *= lam
    state.sx[0] *= lam
    state.s1[0] *= lam
    state.sxe[0] *= lam
    state.se[0] *= lam
    if not np.isnan(v) and not np.isnan(ay) and not np.isnan(r):
        w = dt / (prm.roll_id_noise * prm.roll_id_noise * ROLL_ID_CORRELATION)
        x = r * v
        e = (ay - x) / G
        state.sxx[0] += w * x * x
        state.sx[0] += w * x
        state.s1[0] += w
        state.sxe[0] += w * x * e
        state.se[0] += w * e


@njit(**_JIT)
def roll_gradient_estimate(prm: AttitudeKernelParams,
                           state: AttitudeState) -> tuple[float, float]:
    """The roll gradient k and its one-sigma (rad per m/s²) that :func:`_roll_gradient`'s
    sums and the priors give (k₀ ± σ_k before any sample): the normal equations of (k, b)
    and the inverse of their information; k is clipped to :data:`ROLL_GRADIENT_RANGE`."""
    pk = 1.0 / (prm.roll_gradient_sd * prm.roll_gradient_sd)
    pb = 1.0 / (ROLL_BIAS_SD * ROLL_BIAS_SD)
    m11 = state.sxx[0] + pk
    m12 = state.sx[0]
    m22 = state.s1[0] + pb
    b1 = state.sxe[0] + pk * prm.roll_gradient_prior
    b2 = state.se[0]
    det = m11 * m22 - m12 * m12
    k = (b1 * m22 - m12 * b2) / det
    return (min(max(k, ROLL_GRADIENT_RANGE[0]), ROLL_GRADIENT_RANGE[1]),
            float(np.sqrt(m22 / det)))


@njit(**_JIT)
def _differentiate(z_lp: np.ndarray, z_acc: np.ndarray, z: float, dt: float,
                   wn: float) -> None:
    """One semi-implicit Euler step ``dt`` (s) of the critically damped second-order
    differentiator of corner ``wn`` (rad/s) towards the rate ``z``: ``z_lp`` the filtered rate,
    ``z_acc`` its derivative (1-element arrays, in place)."""
    z_acc[0] += dt * (wn * wn * (z - z_lp[0]) - 2.0 * wn * z_acc[0])
    z_lp[0] += dt * z_acc[0]


@njit(**_JIT)
def attitude_kernel(t: np.ndarray, ax: np.ndarray, ay: np.ndarray, p: np.ndarray,
                    q: np.ndarray, r: np.ndarray, omega: np.ndarray, prm: AttitudeKernelParams,
                    state: AttitudeState, roll: np.ndarray, pitch: np.ndarray,
                    roll_acc: np.ndarray, pitch_acc: np.ndarray, fy_sd: np.ndarray) -> None:
    """Attitude filter over a chunk, in place on ``state`` (:class:`AttitudeState`: φ̂, θ̂,
    the rate differentiators, b̂_p and the roll-gradient regression's five sums).

    ``fy_sd`` (n,): the relative one-sigma that the roll leaves in the road-plane f_y, g σ_k
    where the roll gradient k is identified (no roll rate, no stated suspension; σ_k from
    :func:`roll_gradient_estimate`), 0 elsewhere: the velocity filter's process noise
    takes it.

    ``prm``: :class:`AttitudeKernelParams` (τ_φ, L_θ, c_roll, c_pitch, R, f_acc, the undriven
    axle, e_φ, L_φ, τ_b).

    Roll, with a roll-rate channel, is a complementary filter of the gyro and gravity that
    needs no suspension parameters:
        φ̂̇ = φ̇(p, q, r) − b̂_p + w (φ_g − φ̂)/τ_φ,   b̂̇_p = −w (φ_g − φ̂)/(τ_φ τ_b),
    φ_g = asin((a_y − r v_w)/g), w = 1/(1 + (e/e_φ)²), e = φ_g − φ̂ (a proportional-
    integral complementary filter whose slow integral state b̂_p, time constant τ_b, takes
    the roll-gyro bias). φ̇(p, q, r) and θ̇(q, r) are the Euler rates of the body rates the
    gyro measures (:func:`~vestim.models.kinematics.euler_rates`);
    φ_g is the tilt the IMU's lateral specific force shows beyond the centripetal
    acceleration r·v_x (v_w: the mean R ω of the undriven axle, or of the two middle
    wheels with four driven). φ_g also holds the sideslip acceleration v̇_y, the
    accelerometer bias and the yaw-gyro bias times speed; τ_φ sets the crossover below
    which those are accepted (v̇_y averages out, the biases are ~0.3°). A sliding car has
    a sustained v̇_y that φ_g would read as roll, so the correction fades with its own size
    (Cauchy weight, e_φ), and φ_g is clipped to the roll a lateral load can cause,
    |φ_g| ≤ 0.02 |a_y| + 0.01 rad (0.02 rad per m/s² is softer than any passenger car).
    When the vehicle file states its ``[suspension]`` (L_φ > 0), the quasi-static roll
    c_roll a_y of that suspension replaces φ_g, with the constant gain L_φ: a stated model
    is a fact about the car, and it does not read a slide's v̇_y as roll.

    Pitch is the quasi-static model θ_ss = c_pitch a_x corrected by the Euler pitch rate
    θ̇ = q cos φ − r sin φ with gain L_θ (the plain q would read a rolled body's r sin φ as
    pitch: 0.8° on the crossplant ramp steer x06, and through r tan θ a 0.6° roll error).
    Without a roll rate the quasi-static roll φ_ss = c a_y is used sample by sample
    (NaN rates mean "no rate sensor"), with c = c_roll where the vehicle file states its
    ``[suspension]`` or a calibrated roll gradient, and else c identified online from the
    log itself (:func:`_roll_gradient`: the tilt (a_y − r v)/g regressed on a_y, prior
    k₀ ± σ_k), since a default suspension's gradient is invented and an INS log has none;
    c_roll, c_pitch = m(h − h_c)/k of the [suspension] table (rad per m/s²).

    ``roll_acc``, ``pitch_acc`` (rad/s²): the angular accelerations ṗ, q̇ of the body from
    the rate gyros through a critically damped second-order low-pass differentiator of
    corner frequency f_acc (Hz; 0 where the rate is missing). A gyro with 0.005 rad/s of
    white noise at 200 Hz gives ≈ 0.05 rad/s² of noise at 8 Hz.
    """
    tau, pitch_gain, c_roll, c_pitch, radius = (prm.roll_tau, prm.pitch_gain, prm.c_roll,
                                                prm.c_pitch, prm.radius)
    wn = 2.0 * np.pi * prm.rate_filter_hz
    free = prm.undriven_axle
    e_slide = prm.roll_slide
    model_gain = prm.roll_gain
    tau_b = prm.roll_bias_tau
    k_max, phi_0 = 0.02, 0.01
    for k in range(t.shape[0]):
        k_sd = prm.roll_gradient_sd  # the identified gradient's σ (the prior's until updated)
        if free >= 0:
            v_w = 0.5 * radius * (omega[k, 2 * free] + omega[k, 2 * free + 1])
        else:
            v_w = middle_wheel_speed(omega, k, radius)
        s_g = (ay[k] - r[k] * v_w) / G
        # A body rolls with its lateral load: |φ| ≤ k_max |a_y| + φ_0 (k_max 0.02 rad per
        # m/s², softer than any passenger car; φ_0 for bank and sensor bias).
        lim = min(k_max * abs(ay[k]) + phi_0, 0.5)
        phi_g = np.arcsin(min(max(s_g, -lim), lim))
        if model_gain > 0.0:  # a stated suspension: its quasi-static roll is the reference
            phi_g = c_roll * ay[k]
        th_ss = c_pitch * ax[k]
        if state.started[0] == 0.0:
            c_now = prm.roll_gradient_prior if prm.roll_identify else c_roll
            state.roll[0] = phi_g if not np.isnan(p[k]) else c_now * ay[k]
            state.sxx[0] = 0.0
            state.sx[0] = 0.0
            state.s1[0] = 0.0
            state.sxe[0] = 0.0
            state.se[0] = 0.0
            state.pitch[0] = th_ss
            state.started[0] = 1.0
            state.p_lp[0] = 0.0 if np.isnan(p[k]) else p[k]
            state.q_lp[0] = 0.0 if np.isnan(q[k]) else q[k]
            state.p_acc[0] = 0.0
            state.q_acc[0] = 0.0
            state.roll_bias[0] = 0.0
        else:
            dt = t[k] - state.t_prev[0]
            # Second-order differentiators (semi-implicit Euler, stable for ω_n dt < 2).
            if not np.isnan(p[k]):
                _differentiate(state.p_lp, state.p_acc, p[k], dt, wn)
            if not np.isnan(q[k]):
                _differentiate(state.q_lp, state.q_acc, q[k], dt, wn)
            # Euler rates at the previous sample's attitude (explicit Euler for both angles)
            roll_rate, pitch_rate = euler_rates(0.0 if np.isnan(p[k]) else p[k],
                                                0.0 if np.isnan(q[k]) else q[k], r[k],
                                                state.roll[0], state.pitch[0])
            if np.isnan(p[k]):
                c_now = c_roll
                if prm.roll_identify:
                    _roll_gradient(prm, state, dt, ay[k], r[k], v_w)
                    c_now, k_sd = roll_gradient_estimate(prm, state)
                state.roll[0] = c_now * ay[k]
            else:
                if model_gain > 0.0:
                    state.roll[0] += dt * (roll_rate + model_gain * (phi_g - state.roll[0]))
                else:
                    # Second-order complementary filter: the integral state b̂_p takes the
                    # roll gyro's bias, which a first-order filter would leave as a roll
                    # error b_p τ_φ (0.002 rad/s × 2 s: 80–150 N of gravity in m f_y).
                    err = phi_g - state.roll[0]
                    e = err / e_slide
                    w = 1.0 / (1.0 + e * e)
                    state.roll[0] += dt * (roll_rate - state.roll_bias[0] + w * err / tau)
                    state.roll_bias[0] -= dt * w * err / (tau * tau_b)
            if np.isnan(q[k]):
                state.pitch[0] = th_ss
            else:
                state.pitch[0] += dt * (pitch_rate + pitch_gain * (th_ss - state.pitch[0]))
        state.t_prev[0] = t[k]
        roll[k] = state.roll[0]
        pitch[k] = state.pitch[0]
        roll_acc[k] = state.p_acc[0]
        pitch_acc[k] = state.q_acc[0]
        fy_sd[k] = G * k_sd if (np.isnan(p[k]) and prm.roll_identify) else 0.0


class NormalLoadKernelParams(NamedTuple):
    """Parameters of :func:`normal_loads_kernel` (SI), made by :func:`normal_load_params`."""

    mass: float  # m, kg
    wheelbase: float  # L, m
    cg_height: float  # h, m
    pitch_center_height: float  # h_pc, m
    roll_center_height: float  # h_rc, m
    pitch_stiffness: float  # k_θ, N m/rad
    pitch_damping: float  # c_θ, N m s/rad
    roll_stiffness: float  # k_φ, N m/rad
    roll_damping: float  # c_φ, N m s/rad
    lf: float  # CG to front axle, m
    lr: float  # CG to rear axle, m
    roll_stiffness_front_share: float  # s_f
    track_f: float  # t_f, m
    track_r: float  # t_r, m
    roll_inertia: float  # I_x, kg m²
    pitch_inertia: float  # I_y, kg m²


def normal_load_params(vehicle: Vehicle) -> NormalLoadKernelParams:
    """:class:`NormalLoadKernelParams` from the vehicle file's ``[vehicle]`` and
    ``[suspension]`` (the latter's defaults where the file has none)."""
    b, s = vehicle.body, vehicle.suspension
    return pack(NormalLoadKernelParams, b, pitch_center_height=s.pitch_center_height,
                pitch_stiffness=s.pitch_stiffness, pitch_damping=s.pitch_damping,
                roll_stiffness=s.roll_stiffness, roll_damping=s.roll_damping,
                roll_stiffness_front_share=s.roll_stiffness_front_share,
                roll_inertia=s.roll_inertia, pitch_inertia=s.pitch_inertia)


@njit(**_JIT)
def normal_loads_kernel(f_x: np.ndarray, f_y: np.ndarray, f_z: np.ndarray, roll: np.ndarray,
                        pitch: np.ndarray, roll_rate: np.ndarray, pitch_rate: np.ndarray,
                        roll_acc: np.ndarray, pitch_acc: np.ndarray,
                        prm: NormalLoadKernelParams, dynamic: bool) -> np.ndarray:
    """Normal load per corner (n, 4) in N; ``prm`` from :func:`normal_load_params`.

    See the module docstring for the equations. In dynamic mode a NaN rate falls back to
    the static elastic moment, sample by sample.
    """
    m, L, h = prm.mass, prm.wheelbase, prm.cg_height
    h_pc, h_rc = prm.pitch_center_height, prm.roll_center_height
    k_th, c_th = prm.pitch_stiffness, prm.pitch_damping
    k_ph, c_ph = prm.roll_stiffness, prm.roll_damping
    lf, lr, sf = prm.lf, prm.lr, prm.roll_stiffness_front_share
    t_f, t_r = prm.track_f, prm.track_r
    i_x, i_y = prm.roll_inertia, prm.pitch_inertia
    n = f_x.shape[0]
    out = np.empty((n, 4))
    for k in range(n):
        # Quasi-static moments less the body's angular inertia (the suspension carries
        # m h' a − I ω̇ of the sprung-body balance I ω̇ + c ω + k φ = m h' a).
        m_pitch = -m * (h - h_pc) * f_x[k] - i_y * pitch_acc[k]
        m_roll = m * (h - h_rc) * (f_y[k] + f_z[k] * np.sin(roll[k])) - i_x * roll_acc[k]
        if dynamic:
            if not np.isnan(pitch_rate[k]):
                m_pitch = k_th * pitch[k] + c_th * pitch_rate[k]
            if not np.isnan(roll_rate[k]):
                m_roll = k_ph * roll[k] + c_ph * roll_rate[k]
        dz_long = (-m * h_pc * f_x[k] + m_pitch) / L  # load gained by the front axle
        fzf = m * f_z[k] * lr / L + dz_long
        fzr = m * f_z[k] * lf / L - dz_long
        dlat_f = (m * lr / L * h_rc * f_y[k] + sf * m_roll) / t_f
        dlat_r = (m * lf / L * h_rc * f_y[k] + (1 - sf) * m_roll) / t_r
        out[k, 0] = max(0.5 * fzf - dlat_f, 0.0)
        out[k, 1] = max(0.5 * fzf + dlat_f, 0.0)
        out[k, 2] = max(0.5 * fzr - dlat_r, 0.0)
        out[k, 3] = max(0.5 * fzr + dlat_r, 0.0)
    return out


def normal_loads(f_x: np.ndarray, f_y: np.ndarray, f_z: np.ndarray, roll: np.ndarray,
                 pitch: np.ndarray, roll_rate: np.ndarray, pitch_rate: np.ndarray,
                 roll_acc: np.ndarray, pitch_acc: np.ndarray,
                 vehicle: Vehicle, mode: str = "static") -> np.ndarray:
    """Normal load per corner (n, 4) in N from road-frame specific force and body angles.

    See the module docstring for the equations; ``mode`` "static" or "dynamic".
    NaN rates in dynamic mode fall back to the static elastic moment sample-wise.
    """
    if mode not in MODES:
        raise ValueError(f"normal-load mode {mode!r}: use one of {', '.join(MODES)}")
    arrays = [np.ascontiguousarray(a, dtype=float) for a in (f_x, f_y, f_z, roll, pitch,
                                                              roll_rate, pitch_rate, roll_acc,
                                                              pitch_acc)]
    return normal_loads_kernel(*arrays, normal_load_params(vehicle),
                               _REGISTERED[mode].code == DYNAMIC)


def normal_loads_paper(ax: np.ndarray, ay: np.ndarray, az: np.ndarray, roll: np.ndarray,
                       pitch: np.ndarray, vehicle: Vehicle) -> np.ndarray:
    """Normal loads exactly as printed in 001 eq. (14)–(17) (= 000 eq. (13)–(14)), for comparison.

    ā_θx = a_x cos θ + a_z sin θ, ā_θz = a_z cos θ − a_x sin θ,
    F_zf = −m(h ā_θx − l_r ā_θz)/L, F_zr = m(h ā_θx + l_f ā_θz)/L,
    ā_φy = a_y cos φ + a_z sin φ, ā_φz = a_z cos φ − a_y sin φ, m_i = F_zi/g,
    F_ziL = m_i/T_i [ā_φz (T_i/2 − h_rc sin φ) − ā_φy h],
    F_ziR = m_i/T_i [ā_φz (T_i/2 + h_rc sin φ) + ā_φy h].
    The paper's roll sign convention is opposite to the spec's; φ is negated here
    so that both describe the same body motion.
    """
    b = vehicle.body
    m, L, h = b.mass, b.wheelbase, b.cg_height
    phi = -roll
    a_tx = ax * np.cos(pitch) + az * np.sin(pitch)
    a_tz = az * np.cos(pitch) - ax * np.sin(pitch)
    fzf = -m / L * (h * a_tx - b.lr * a_tz)
    fzr = m / L * (h * a_tx + b.lf * a_tz)
    a_py = ay * np.cos(phi) + az * np.sin(phi)
    a_pz = az * np.cos(phi) - ay * np.sin(phi)
    out = np.empty((ax.shape[0], 4))
    for col, fz_axle, track in ((0, fzf, b.track_f), (2, fzr, b.track_r)):
        mi = fz_axle / G
        shift = b.roll_center_height * np.sin(phi)
        out[:, col] = mi / track * (a_pz * (track / 2 - shift) - a_py * h)
        out[:, col + 1] = mi / track * (a_pz * (track / 2 + shift) + a_py * h)
    return out
