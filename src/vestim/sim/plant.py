"""Ground-truth plant: double-track chassis with roll/pitch modes, four wheels, two tire plants.

The whole simulation runs in one compiled kernel (:func:`simulate_kernel`):
fixed-step fourth-order integration at ``dt`` (1 kHz by default) — classical
RK4, in its exponential form ETDRK4 for the LuGre deflections, whose decay
rate reaches 1e5 1/s when a tire slides on ice — the driver /
pedal maps / traction control / ABS evaluated once per step, and the sensor
and ground-truth channels recorded every ``stride`` steps.

Model (ISO 8855 body axes, x forward, y left, z up; corners fl, fr, rl, rr):

* Planar rigid body on the road plane (grade γ along the path, bank β across):
  m(v̇x − r vy) = ΣFx − ½ρC_dA vx|vx| − m g sin γ,
  m(v̇y + r vx) = ΣFy − m g sin β cos γ,   Iz ṙ = Σ(x_i Fy_i − y_i Fx_i).
* Sprung body roll φ and pitch θ relative to the road as damped second-order
  modes about the roll axis (height h_rc) and the pitch centre (height h_pc):
  Iφ φ̈ = m(h − h_rc)(f_y cos φ + f_z sin φ) − kφ φ − cφ φ̇,
  Iθ θ̈ = −m(h − h_pc)(f_x cos θ − f_z sin θ) − kθ θ − cθ θ̇,
  where f = a − g is the specific force in the road frame.
* Normal loads: static + geometric transfer through the roll axis / pitch
  centre + elastic transfer through the suspension springs and dampers,
  Fz_fl = ½m f_z l_r/L − (m h_pc f_x − kθθ − cθθ̇)/(2L) − [m (l_r/L) h_rc f_y + s_f(kφφ + cφφ̇)]/t_f
  (and the mirror images). In steady state the transfers add up to m h f_x / L
  and m h f_y, the textbook quasi-static result. The geometric part uses the
  specific force through a 5 ms lag to break the algebraic loop force → load → force.
* Wheels: I_w ω̇_i = T_i − R Fx_i − f R Fz_i sat(ω_i), with T_i the net drive/brake torque.
* Tires (``tire_kind``): 0 = combined-slip LuGre, states z_x, z_y (004 eq. (6)–(7));
  1 = combined-slip Magic Formula with relaxation-length transient slip,
  states u_x, u_y: u̇_x = (Rω − v_xt) − |v_xt| u_x/σ_x, u̇_y = v_yt − |v_xt| u_y/σ_y,
  slip ratio κ = u_x/σ_x, slip angle α = atan(u_y/σ_y), plus carcass damping
  Fz·d·u̇ (zero in steady state); the deflections stop growing at |κ| = 1,
  |tan α| = 3, where the tire slides (else they grow without bound at low speed).
* IMU at the CG, fixed to the sprung body: the road-frame specific force rotated
  by pitch then roll; the small accelerations of the body's own roll and pitch
  motion are neglected.

Simplifications, stated once: no steering compliance, no camber, no aerodynamic
lift, rolling resistance as a wheel moment (so ``ref_fx`` at a free-rolling
wheel is −f·Fz, as a wheel-force transducer would read).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.models.tire import (
    lugre_rates,
    lugre_small_slip_stiffness,
    lugre_zdot,
    magic_formula,
    mf_stiffness,
)

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

# ---------------------------------------------------------------- state layout
DIST, PSI, POS_X, POS_Y, VX, VY, YAW_RATE, ROLL, ROLL_RATE, PITCH, PITCH_RATE = range(11)
OMEGA = 11  # 4 wheel speeds, rad/s
TIRE_A = 15  # 4 tire states: LuGre z_x (m) or MF u_x (m)
TIRE_B = 19  # 4 tire states: LuGre z_y (m) or MF u_y (m)
FX_LAG, FY_LAG = 23, 24  # lagged road-frame specific force for the geometric load transfer
N_STATE = 25

# ------------------------------------------------------------ parameter layout
(P_M, P_IZ, P_IW, P_LF, P_LR, P_TF, P_TR, P_H, P_HRC, P_R, P_IPHI, P_ITH, P_KPHI, P_CPHI,
 P_KTH, P_CTH, P_SF, P_HPC, P_DRAG, P_FRR, P_TIRE, P_TAU_LAG,
 # LuGre
 P_S0X, P_S1X, P_S2X, P_KAX, P_S0Y, P_S1Y, P_S2Y, P_KAY, P_MUS, P_MUC, P_VS, P_ALPHA,
 # Magic Formula
 P_FZ0, P_CX, P_EX, P_KX, P_KXL, P_CY, P_EY, P_KY1, P_KY2, P_RBX1, P_RBX2, P_RBY1, P_RBY2,
 P_RELX, P_RELY, P_DAMPX, P_DAMPY,
 # powertrain, brakes, controllers
 P_TDMAX, P_PMAX, P_FRONT_DRIVE, P_TBMAX, P_FRONT_BRAKE, P_VMAX, P_TC, P_ABS, P_KP_SPEED, P_KI_SPEED,
 N_PARAM) = range(62)

TIRE_LUGRE, TIRE_MAGIC = 0, 1
MF_SLIP_SAT = 1.0  # |κ'| at which the Magic Formula tire's deflection stops growing
MF_TAN_SAT = 3.0  # |tan α'| likewise (α' ≈ 72°)

# ------------------------------------------------------------- output layout
# Per-step algebraic outputs, filled by _derivatives for recording.
O_FXT, O_FYT, O_FZ, O_VXT, O_VYT = 0, 4, 8, 12, 16  # 4 each (tire frame, N / m/s)
O_VXW, O_VYW = 20, 24  # wheel-centre velocity, body frame, m/s
O_AX, O_AY, O_AZ = 28, 29, 30  # IMU specific force, body frame, m/s²
N_OUT = 31

# Recorded columns (one row per sensor sample), kept in one table for the Python side.
REC_NAMES: tuple[str, ...] = (
    "t",
    "omega_fl", "omega_fr", "omega_rl", "omega_rr",
    "torque_fl", "torque_fr", "torque_rl", "torque_rr",
    "ax", "ay", "az", "yaw_rate", "roll_rate", "pitch_rate",
    "delta_fl", "delta_fr",
    "ref_vx", "ref_vy",
    "ref_vx_fl", "ref_vx_fr", "ref_vx_rl", "ref_vx_rr",
    "ref_vy_fl", "ref_vy_fr", "ref_vy_rl", "ref_vy_rr",
    "ref_fx_fl", "ref_fx_fr", "ref_fx_rl", "ref_fx_rr",
    "ref_fy_fl", "ref_fy_fr", "ref_fy_rl", "ref_fy_rr",
    "ref_fz_fl", "ref_fz_fr", "ref_fz_rl", "ref_fz_rr",
    "ref_slip_ratio_fl", "ref_slip_ratio_fr", "ref_slip_ratio_rl", "ref_slip_ratio_rr",
    "ref_slip_angle_fl", "ref_slip_angle_fr", "ref_slip_angle_rl", "ref_slip_angle_rr",
    "ref_mu_fl", "ref_mu_fr", "ref_mu_rl", "ref_mu_rr",
    "ref_roll", "ref_pitch",
    "ref_stiffness_cx_f", "ref_stiffness_cx_r", "ref_stiffness_cy_f", "ref_stiffness_cy_r",
    "x", "y", "yaw", "distance", "grade", "bank",
)
N_REC = len(REC_NAMES)


class RoadTables(NamedTuple):
    """The road under the wheels, tabulated (:class:`~vestim.sim.road.Road`).

    Attributes:
        knots: (K,) s, or m of travelled distance where ``by_distance``.
        mu, scale: (K, 4) friction coefficient and tire stiffness factor per wheel (fl, fr, rl, rr).
        by_distance: the tables run over distance (else time).
        geo_knots: (G,) m of travelled distance. grade, bank: (G,) rad.
    """

    knots: np.ndarray
    mu: np.ndarray
    scale: np.ndarray
    by_distance: bool
    geo_knots: np.ndarray
    grade: np.ndarray
    bank: np.ndarray


class PlantParams(NamedTuple):
    """What :func:`simulate_kernel` holds fixed over a run (packed by
    :func:`vestim.sim.simulate.kernel_params`).

    Attributes:
        p: (``N_PARAM``,) vehicle and maneuver parameters (``P_*``, SI).
        xw, yw: (4,) wheel positions from the CG, body frame (m).
        dt: integration step (s). stride: steps per recorded row.
        road: the road tables (:class:`RoadTables`).
        theta_mu, theta_val: θ(μ) of the LuGre plant, interpolated in μ.
    """

    p: np.ndarray
    xw: np.ndarray
    yw: np.ndarray
    dt: float
    stride: int
    road: RoadTables
    theta_mu: np.ndarray
    theta_val: np.ndarray


class PlantState(NamedTuple):
    """What :func:`simulate_kernel` advances in place between chunks.

    Attributes:
        x: (``N_STATE``,) the plant state (layout ``DIST`` … ``FY_LAG``).
        ctrl: (9,) controller memory: traction-control torque factors (4), ABS brake-torque
            factors (4), the speed-hold integrator (m).
    """

    x: np.ndarray
    ctrl: np.ndarray


class DriverInputs(NamedTuple):
    """Per-step inputs of :func:`simulate_kernel` (zero-order hold over a step).

    Attributes:
        delta_fl, delta_fr: road-wheel angles (rad).
        throttle, brake: pedal positions in [0, 1].
        v_target: target speed of the driver's speed hold (m/s), NaN where the pedals are
            open-loop.
    """

    delta_fl: np.ndarray
    delta_fr: np.ndarray
    throttle: np.ndarray
    brake: np.ndarray
    v_target: np.ndarray


@njit(**_JIT)
def _sat(x: float, width: float) -> float:
    """Smooth-enough sign: linear within ±width, ±1 outside (brakes, rolling resistance)."""
    return min(1.0, max(-1.0, x / width))


@njit(**_JIT)
def _derivatives(x: np.ndarray, p: np.ndarray, xw: np.ndarray, yw: np.ndarray,
                 delta: np.ndarray, torque: np.ndarray, mu: np.ndarray, theta: np.ndarray,
                 scale: np.ndarray, grade: float, bank: float,
                 dx: np.ndarray, out: np.ndarray) -> None:
    """Right-hand side ẋ = f(x, u); also fills ``out`` with forces, loads and IMU readings."""
    m = p[P_M]
    L = p[P_LF] + p[P_LR]
    R = p[P_R]
    vx, vy, r = x[VX], x[VY], x[YAW_RATE]
    phi, phid, th, thd = x[ROLL], x[ROLL_RATE], x[PITCH], x[PITCH_RATE]

    # Gravity in the road frame (grade along the path, bank across), m/s².
    g_x = -G * math.sin(grade)
    g_y = -G * math.sin(bank) * math.cos(grade)
    g_z = -G * math.cos(bank) * math.cos(grade)
    f_z = -g_z  # road-frame vertical specific force (no vertical acceleration)

    # Normal loads: static + geometric (lagged) + elastic transfer.
    fxl, fyl = x[FX_LAG], x[FY_LAG]
    m_pitch = p[P_KTH] * th + p[P_CTH] * thd
    m_roll = p[P_KPHI] * phi + p[P_CPHI] * phid
    dz_long = (-m * p[P_HPC] * fxl + m_pitch) / L  # load gained by the front axle
    dz_lat_f = (m * p[P_LR] / L * p[P_HRC] * fyl + p[P_SF] * m_roll) / p[P_TF]
    dz_lat_r = (m * p[P_LF] / L * p[P_HRC] * fyl + (1.0 - p[P_SF]) * m_roll) / p[P_TR]
    fzf = 0.5 * (m * f_z * p[P_LR] / L + dz_long)
    fzr = 0.5 * (m * f_z * p[P_LF] / L - dz_long)
    fz0 = max(fzf - dz_lat_f, 0.0)
    fz1 = max(fzf + dz_lat_f, 0.0)
    fz2 = max(fzr - dz_lat_r, 0.0)
    fz3 = max(fzr + dz_lat_r, 0.0)

    sum_fx = 0.0
    sum_fy = 0.0
    sum_mz = 0.0
    for i in range(4):
        fz = fz0 if i == 0 else fz1 if i == 1 else fz2 if i == 2 else fz3
        # Wheel-centre velocity (body frame) and in the tire frame.
        vxw = vx - r * yw[i]
        vyw = vy + r * xw[i]
        cd, sd = math.cos(delta[i]), math.sin(delta[i])
        vxt = vxw * cd + vyw * sd
        vyt = -vxw * sd + vyw * cd
        om = x[OMEGA + i]
        a_state = x[TIRE_A + i]
        b_state = x[TIRE_B + i]
        if p[P_TIRE] == TIRE_LUGRE:
            vrx = R * om - vxt
            vry = -vyt
            dzx, dzy = lugre_zdot(a_state, b_state, vrx, vry, R * abs(om), theta[i],
                                  scale[i] * p[P_S0X], scale[i] * p[P_S0Y], p[P_KAX], p[P_KAY],
                                  p[P_MUS], p[P_MUC], p[P_VS], p[P_ALPHA])
            mux = scale[i] * p[P_S0X] * a_state + p[P_S1X] * dzx + p[P_S2X] * vrx
            muy = scale[i] * p[P_S0Y] * b_state + p[P_S1Y] * dzy + p[P_S2Y] * vry
            fxt = fz * mux
            fyt = fz * muy
            dx[TIRE_A + i] = dzx
            dx[TIRE_B + i] = dzy
        else:
            kappa = a_state / p[P_RELX]
            alpha = math.atan(b_state / p[P_RELY])
            fxt, fyt = magic_formula(kappa, alpha, fz, mu[i], scale[i],
                                     p[P_FZ0], p[P_CX], p[P_EX], p[P_KX], p[P_KXL],
                                     p[P_CY], p[P_EY], p[P_KY1], p[P_KY2],
                                     p[P_RBX1], p[P_RBX2], p[P_RBY1], p[P_RBY2])
            dux = (R * om - vxt) - abs(vxt) * kappa
            duy = vyt - abs(vxt) * b_state / p[P_RELY]
            # A sliding tire's deflection saturates: beyond |κ'| = 1 (|tan α'| = 3)
            # the tread slides instead of deflecting further. Without this limit the
            # deflection of a tire spinning at low speed grows without bound.
            if (kappa >= MF_SLIP_SAT and dux > 0.0) or (kappa <= -MF_SLIP_SAT and dux < 0.0):
                dux = 0.0
            tan_a = b_state / p[P_RELY]
            if (tan_a >= MF_TAN_SAT and duy > 0.0) or (tan_a <= -MF_TAN_SAT and duy < 0.0):
                duy = 0.0
            dx[TIRE_A + i] = dux
            dx[TIRE_B + i] = duy
            # Carcass damping on the deflection rates (as σ1·ż in LuGre): without it
            # the wheel/tread mode (~35 Hz) is almost undamped at low speed.
            # Friction bounds what the tread transmits, damping included.
            f_max = mu[i] * fz
            fxt = min(max(fxt + fz * p[P_DAMPX] * dux, -f_max), f_max)
            fyt = min(max(fyt - fz * p[P_DAMPY] * duy, -f_max), f_max)
        # Wheel spin: net torque minus tire force moment minus rolling resistance.
        dx[OMEGA + i] = (torque[i] - R * fxt - p[P_FRR] * R * fz * _sat(om, 0.5)) / p[P_IW]
        fxb = fxt * cd - fyt * sd
        fyb = fxt * sd + fyt * cd
        sum_fx += fxb
        sum_fy += fyb
        sum_mz += xw[i] * fyb - yw[i] * fxb
        out[O_FXT + i] = fxt
        out[O_FYT + i] = fyt
        out[O_FZ + i] = fz
        out[O_VXT + i] = vxt
        out[O_VYT + i] = vyt
        out[O_VXW + i] = vxw
        out[O_VYW + i] = vyw

    drag = p[P_DRAG] * vx * abs(vx)
    a_x = (sum_fx - drag) / m + g_x  # road-frame acceleration of the CG
    a_y = sum_fy / m + g_y
    dx[VX] = a_x + r * vy
    dx[VY] = a_y - r * vx
    dx[YAW_RATE] = sum_mz / p[P_IZ]
    f_x = a_x - g_x
    f_y = a_y - g_y

    dx[ROLL] = phid
    dx[ROLL_RATE] = (m * (p[P_H] - p[P_HRC]) * (f_y * math.cos(phi) + f_z * math.sin(phi))
                     - m_roll) / p[P_IPHI]
    dx[PITCH] = thd
    dx[PITCH_RATE] = (-m * (p[P_H] - p[P_HPC]) * (f_x * math.cos(th) - f_z * math.sin(th))
                      - m_pitch) / p[P_ITH]
    dx[FX_LAG] = (f_x - fxl) / p[P_TAU_LAG]
    dx[FY_LAG] = (f_y - fyl) / p[P_TAU_LAG]

    psi = x[PSI]
    dx[DIST] = vx  # travelled distance along the path (signed)
    dx[PSI] = r
    dx[POS_X] = vx * math.cos(psi) - vy * math.sin(psi)
    dx[POS_Y] = vx * math.sin(psi) + vy * math.cos(psi)

    # IMU specific force in the sprung-body frame: rotate by pitch θ, then roll φ.
    sp, cp = math.sin(phi), math.cos(phi)
    st, ct = math.sin(th), math.cos(th)
    tmp_z = st * f_x + ct * f_z
    out[O_AX] = ct * f_x - st * f_z
    out[O_AY] = cp * f_y + sp * tmp_z
    out[O_AZ] = -sp * f_y + cp * tmp_z


@njit(**_JIT)
def _phi(z: float, k: int) -> float:
    """φ_k(z) of exponential integrators: φ1 = (e^z − 1)/z, φ2 = (e^z − 1 − z)/z², φ3 = ….

    Taylor series φ_k(z) = Σ z^n/(n + k)! for |z| < 0.5 (the closed forms cancel there).
    """
    if abs(z) < 0.5:
        term = 1.0
        for n in range(1, k + 1):
            term /= n
        total = term
        for n in range(1, 12):
            term *= z / (n + k)
            total += term
        return total
    if k == 1:
        return (math.exp(z) - 1.0) / z
    if k == 2:
        return (math.exp(z) - 1.0 - z) / (z * z)
    return (math.exp(z) - 1.0 - z - 0.5 * z * z) / (z * z * z)


@njit(**_JIT)
def _interp_col(xq: float, knots: np.ndarray, values: np.ndarray, col: int) -> float:
    """Piecewise-linear interpolation of column ``col`` of ``values`` (K, 4); held at the ends."""
    k = knots.shape[0]
    if xq <= knots[0]:
        return values[0, col]
    if xq >= knots[k - 1]:
        return values[k - 1, col]
    j = np.searchsorted(knots, xq) - 1
    w = (xq - knots[j]) / (knots[j + 1] - knots[j])
    return (1.0 - w) * values[j, col] + w * values[j + 1, col]


@njit(**_JIT)
def simulate_kernel(prm: PlantParams, st: PlantState, inp: DriverInputs, k0: int) -> np.ndarray:
    """Integrate the plant over the steps of ``inp`` (ETDRK4 at ``prm.dt``); record every
    ``prm.stride`` steps.

    The road is tabulated over time or travelled distance (``prm.road``): μ and a stiffness
    factor per wheel, grade and bank (rad) over distance. θ(μ) for the LuGre plant is
    interpolated from (``theta_mu``, ``theta_val``).

    The kernel may be called in chunks: ``st`` (the state and the controller memory) is
    updated in place, and ``k0`` is the index of the chunk's first step.

    Returns:
        Array (n_records, N_REC) with the columns of :data:`REC_NAMES`.
    """
    p, xw, yw, dt, stride = prm.p, prm.xw, prm.yw, prm.dt, prm.stride
    road_knots, road_mu, road_scale = prm.road.knots, prm.road.mu, prm.road.scale
    road_by_distance = prm.road.by_distance
    geo_knots, geo_grade, geo_bank = prm.road.geo_knots, prm.road.grade, prm.road.bank
    theta_mu, theta_val = prm.theta_mu, prm.theta_val
    delta_fl, delta_fr, throttle, brake = inp.delta_fl, inp.delta_fr, inp.throttle, inp.brake
    v_target = inp.v_target
    x0, ctrl = st.x, st.ctrl
    n = throttle.shape[0]
    n_rec = (n + stride - 1) // stride
    rec = np.empty((n_rec, N_REC))
    x = x0
    k1 = np.empty(N_STATE)
    k2 = np.empty(N_STATE)
    k3 = np.empty(N_STATE)
    k4 = np.empty(N_STATE)
    xs = np.empty(N_STATE)
    xa = np.empty(N_STATE)
    lin = np.zeros(N_STATE)
    e_half = np.empty(N_STATE)
    e_full = np.empty(N_STATE)
    phi1_half = np.empty(N_STATE)
    w1 = np.empty(N_STATE)
    w2 = np.empty(N_STATE)
    w3 = np.empty(N_STATE)
    out = np.empty(N_OUT)
    delta = np.zeros(4)
    torque = np.zeros(4)
    mu = np.empty(4)
    theta = np.empty(4)
    scale = np.empty(4)
    tc = ctrl[0:4]  # traction-control torque factors (views: updated in place)
    ab = ctrl[4:8]  # ABS brake-torque factors
    integ = ctrl[8]  # speed-hold integrator
    R = p[P_R]
    front_drive = p[P_FRONT_DRIVE]
    drive_share = np.array([front_drive, front_drive, 1.0 - front_drive, 1.0 - front_drive]) * 0.5
    fb = p[P_FRONT_BRAKE]
    brake_share = np.array([fb, fb, 1.0 - fb, 1.0 - fb]) * 0.5
    slip = np.empty(4)

    for k in range(n):
        t = (k0 + k) * dt
        delta[0] = delta_fl[k]
        delta[1] = delta_fr[k]
        # Road under each wheel, held over the step (distance-based: the front
        # wheels reach a surface change lf + lr before the rear ones).
        for i in range(4):
            pos = x[DIST] + xw[i] if road_by_distance else t
            mu[i] = _interp_col(pos, road_knots, road_mu, i)
            scale[i] = _interp_col(pos, road_knots, road_scale, i)
            theta[i] = np.interp(mu[i], theta_mu, theta_val)
        grade = np.interp(x[DIST], geo_knots, geo_grade)
        bank = np.interp(x[DIST], geo_knots, geo_bank)

        # Driver: open-loop pedals, or a PI speed hold on the true speed.
        thr = throttle[k]
        brk = brake[k]
        if not math.isnan(v_target[k]):
            err = v_target[k] - x[VX]
            integ = min(max(integ + err * dt, -5.0), 5.0)
            ctrl[8] = integ
            u = p[P_KP_SPEED] * err + p[P_KI_SPEED] * integ
            thr = min(max(u, 0.0), 1.0)
            brk = min(max(-u, 0.0), 1.0)
        mean_speed = 0.25 * (abs(x[OMEGA]) + abs(x[OMEGA + 1]) + abs(x[OMEGA + 2])
                             + abs(x[OMEGA + 3]))
        t_drive = thr * min(p[P_TDMAX], p[P_PMAX] / max(mean_speed, 1.0))
        t_brake = brk * p[P_TBMAX]

        # Tire-frame slip ratio (spec definition) for TC / ABS, from the true state:
        # the controllers stand for an ideal ESC unit, not for an estimator. With
        # TC on, a vehicle sideslip beyond 0.1 rad also cuts the drive torque of
        # every wheel (the stability-control part of TC).
        r_now = x[YAW_RATE]
        if p[P_TC] > 0.0 and abs(x[VY]) > 0.1 * max(abs(x[VX]), 1.0):
            for i in range(4):
                tc[i] = max(0.0, tc[i] - 0.05)
        for i in range(4):
            vxw = x[VX] - r_now * yw[i]
            vyw = x[VY] + r_now * xw[i]
            vxt = vxw * math.cos(delta[i]) + vyw * math.sin(delta[i])
            rw = R * x[OMEGA + i]
            den = max(abs(rw), abs(vxt), 0.5)
            slip[i] = (rw - vxt) / den
            if p[P_TC] > 0.0:
                if slip[i] > 0.15:
                    tc[i] = max(0.0, tc[i] - 0.3)
                elif slip[i] < 0.08:
                    tc[i] = min(1.0, tc[i] + 0.02)
            if p[P_ABS] > 0.0:
                if slip[i] < -0.15:
                    ab[i] = max(0.0, ab[i] - 0.3)
                elif slip[i] > -0.08:
                    ab[i] = min(1.0, ab[i] + 0.02)
            fade = min(1.0, max(0.0, (p[P_VMAX] - abs(rw)) / (0.1 * p[P_VMAX])))
            torque[i] = (tc[i] * fade * t_drive * drive_share[i]
                         - ab[i] * t_brake * brake_share[i] * _sat(x[OMEGA + i], 0.5))

        if k % stride == 0:
            _derivatives(x, p, xw, yw, delta, torque, mu, theta, scale, grade, bank, k1, out)
            _record(rec[k // stride], t, x, p, out, delta, torque, mu, scale, grade, bank)

        # One ETDRK4 step (Cox & Matthews 2002). The LuGre deflections decay at
        # rates up to ~1e5 1/s when a tire slides on ice; that linear part −a·z is
        # integrated exactly (per wheel, rate frozen over the step), everything
        # else as classical RK4, to which ETDRK4 reduces where the rate is zero.
        for j in range(N_STATE):
            lin[j] = 0.0
        if p[P_TIRE] == TIRE_LUGRE:
            for i in range(4):
                lx, ly = lugre_rates(R * x[OMEGA + i] - out[O_VXT + i], -out[O_VYT + i],
                                     R * abs(x[OMEGA + i]), theta[i],
                                     scale[i] * p[P_S0X], scale[i] * p[P_S0Y],
                                     p[P_KAX], p[P_KAY], p[P_MUS], p[P_MUC], p[P_VS],
                                     p[P_ALPHA])
                lin[TIRE_A + i] = -lx
                lin[TIRE_B + i] = -ly
        for j in range(N_STATE):
            zh = lin[j] * dt
            e_half[j] = math.exp(0.5 * zh)
            e_full[j] = math.exp(zh)
            phi1_half[j] = _phi(0.5 * zh, 1)
            p1, p2, p3 = _phi(zh, 1), _phi(zh, 2), _phi(zh, 3)
            w1[j] = p1 - 3.0 * p2 + 4.0 * p3
            w2[j] = 2.0 * p2 - 4.0 * p3
            w3[j] = 4.0 * p3 - p2
        h2 = 0.5 * dt
        _derivatives(x, p, xw, yw, delta, torque, mu, theta, scale, grade, bank, k1, out)
        for j in range(N_STATE):
            k1[j] -= lin[j] * x[j]  # N(u) = f(u) − L u
            xa[j] = e_half[j] * x[j] + h2 * phi1_half[j] * k1[j]
        _derivatives(xa, p, xw, yw, delta, torque, mu, theta, scale, grade, bank, k2, out)
        for j in range(N_STATE):
            k2[j] -= lin[j] * xa[j]
            xs[j] = e_half[j] * x[j] + h2 * phi1_half[j] * k2[j]
        _derivatives(xs, p, xw, yw, delta, torque, mu, theta, scale, grade, bank, k3, out)
        for j in range(N_STATE):
            k3[j] -= lin[j] * xs[j]
            xs[j] = e_half[j] * xa[j] + h2 * phi1_half[j] * (2.0 * k3[j] - k1[j])
        _derivatives(xs, p, xw, yw, delta, torque, mu, theta, scale, grade, bank, k4, out)
        for j in range(N_STATE):
            k4[j] -= lin[j] * xs[j]
            x[j] = e_full[j] * x[j] + dt * (w1[j] * k1[j] + w2[j] * (k2[j] + k3[j])
                                            + w3[j] * k4[j])
    return rec


@njit(**_JIT)
def _record(row: np.ndarray, t: float, x: np.ndarray, p: np.ndarray, out: np.ndarray,
            delta: np.ndarray, torque: np.ndarray, mu: np.ndarray, scale: np.ndarray,
            grade: float, bank: float) -> None:
    """One row of :data:`REC_NAMES` from the state and the outputs of ``_derivatives``."""
    R = p[P_R]
    row[0] = t
    for i in range(4):
        row[1 + i] = x[OMEGA + i]
        row[5 + i] = torque[i]
    row[9] = out[O_AX]
    row[10] = out[O_AY]
    row[11] = out[O_AZ]
    # The gyro measures body rates: the Euler rates φ̇, θ̇, ψ̇ of the rolled and pitched
    # body (Z-Y-X) rotated into it; a rolled body in a turn reads ψ̇ sin φ on its pitch axis.
    sp, cp = math.sin(x[ROLL]), math.cos(x[ROLL])
    st, ct = math.sin(x[PITCH]), math.cos(x[PITCH])
    row[12] = x[YAW_RATE] * ct * cp - x[PITCH_RATE] * sp
    row[13] = x[ROLL_RATE] - x[YAW_RATE] * st
    row[14] = x[PITCH_RATE] * cp + x[YAW_RATE] * ct * sp
    row[15] = delta[0]
    row[16] = delta[1]
    row[17] = x[VX]
    row[18] = x[VY]
    cx_f = 0.0
    cx_r = 0.0
    cy_f = 0.0
    cy_r = 0.0
    for i in range(4):
        vxt = out[O_VXT + i]
        vyt = out[O_VYT + i]
        rw = R * x[OMEGA + i]
        row[19 + i] = out[O_VXW + i]
        row[23 + i] = out[O_VYW + i]
        row[27 + i] = out[O_FXT + i]
        row[31 + i] = out[O_FYT + i]
        row[35 + i] = out[O_FZ + i]
        # Spec: (Rω − v_xt)/max(Rω, v_xt); magnitudes in the denominator keep it
        # bounded when the car stops or slides backwards (identical when moving forward).
        den = max(abs(rw), abs(vxt))
        row[39 + i] = (rw - vxt) / den if den > 1e-6 else 0.0
        row[43 + i] = math.atan(vyt / vxt) if abs(vxt) > 1e-6 else 0.0
        row[47 + i] = mu[i]
        fz = out[O_FZ + i]
        if p[P_TIRE] == TIRE_LUGRE:
            cxi, cyi = lugre_small_slip_stiffness(fz, R * abs(x[OMEGA + i]), scale[i],
                                                  p[P_S0X], p[P_S2X], p[P_KAX],
                                                  p[P_S0Y], p[P_S2Y], p[P_KAY])
        else:
            cxi, cyi = mf_stiffness(fz, scale[i], p[P_FZ0], p[P_KX], p[P_KXL], p[P_KY1],
                                    p[P_KY2])
        if i < 2:
            cx_f += cxi
            cy_f += cyi
        else:
            cx_r += cxi
            cy_r += cyi
    row[51] = x[ROLL]
    row[52] = x[PITCH]
    row[53] = cx_f
    row[54] = cx_r
    row[55] = cy_f
    row[56] = cy_r
    row[57] = x[POS_X]
    row[58] = x[POS_Y]
    row[59] = x[PSI]
    row[60] = x[DIST]
    row[61] = grade
    row[62] = bank


__all__ = ["N_PARAM", "N_STATE", "REC_NAMES", "DriverInputs", "PlantParams", "PlantState",
           "RoadTables", "simulate_kernel"]
