"""Single-track estimation model of 002 Sec. II, eq. (1)–(12), with the stiffness deviation as noise.

State x = [v_x, v_y, ψ̇] (m/s, m/s, rad/s; indices :data:`VX`, :data:`VY`,
:data:`YAW_RATE`); input u = [δ, ω_f, ω_r, T_s] (road-wheel angle in rad, axle-mean
wheel speeds in rad/s, step length in s; indices ``U_*``); measurement
y = [a_x, a_y, ψ̇] (m/s², m/s², rad/s; indices ``M_*``); stiffness deviation
w = [ΔC^x, ΔC_f^y, ΔC_r^y] (N per unit slip ratio, N/rad, N/rad; indices ``W_*``).

Physics (002 eq. (1)–(4), axle totals, ISO 8855 signs):

    m(v̇_x − v_y ψ̇) = F_f^x cos δ − F_f^y sin δ + F_r^x − D          (1a)
    m(v̇_y + v_x ψ̇) = F_f^y cos δ + F_r^y + F_f^x sin δ             (1b)
    I ψ̈ = l_f (F_f^y cos δ + F_f^x sin δ) − l_r F_r^y                (1c)
    F^x = C^x λ,  F^y = C^y α                                        (2)
    λ = (R ω − v_x)/max(R ω, v_x)                                    (3)
    α_f = δ − (v_y + l_f ψ̇)/v_x,  α_r = (l_r ψ̇ − v_y)/v_x           (4)

Deviations from the printed text, each the physically consistent reading:

* D = ½ ρ C_d A v_x|v_x| is the aerodynamic drag, known from the vehicle file
  (002 Assumption 4 neglects it). At 22 m/s it is 0.14 m/s² for the SUV, 15 %
  of the a_x signal of the 002 study; left out, it biases ΔC^x and, through the
  v_x dynamics, lets v_x drift during braking.
* eq. (3) prints λ = (v_x − Rω)/max(·), which makes F^x = C^x λ pull backwards
  under traction; we use the sign of the log spec (traction λ > 0, F^x > 0).
* eq. (12) prints d = [T_s g_1ᵀ, T_s g_2ᵀ, 0]ᵀ. With g = T_s ∂ẋ/∂w (eq. (10))
  the acceleration sensitivity is ∂a/∂w = g_{1,2}/T_s, not T_s g_{1,2}
  (wrong by T_s², a factor 4·10⁴ at 200 Hz); d here is ∂[a_x, a_y, ψ̇]/∂w.
* v_x in the denominators is bounded below by ``v_min`` (the model is singular
  at standstill; the filter is not activated there, see 002 Sec. V).

Longitudinal deviation by drivetrain (002 after eq. (8)): w[W_CX] is ΔC_f^x for
FWD and AWD and ΔC_r^x for RWD. 002 keeps the other axle's longitudinal
stiffness at its nominal value. We let it follow the same *relative* change,
ΔC_r^x = w_x · C_{r,n}^x / C_{f,n}^x for FWD and AWD (ΔC_f^x = w_x · C_{f,n}^x /
C_{r,n}^x for RWD): one road under both axles changes both longitudinal slip
stiffnesses alike, and the nominal ratio is the static load ratio of the generic
prior (C ∝ F_z). The undriven axle is what ties v_x to the wheel speeds during
braking (the brakes act on all four wheels). Held at nominal as in 002, its
error after a road change biases w_x (on the cross-plant logs the braked axle
pulled the estimate 10–30 % off); tied instead to the same axle's cornering
stiffness (ΔC^x = ΔC^y C_n^x/C_n^y, the previous choice) it inherits the ratio
C^x/C^y of the prior (2 for the generic prior), which a real tire need not have
(PAC2002 of the cross-plant logs: ≈ 1), and its braking force came out twice
the plant's, which the filter paid for with C^x 20–56 % low. For AWD 002
suggests estimating front and rear ΔC^x "iteratively"; with similar slip on
both axles a_x only observes their sum, so the common relative change is what
is identifiable. The ties are carried in the parameter vector (``P_KXF``,
``P_KXR``, ``P_TXF``, ``P_TXR``; the τ terms are zero with this choice).

The dynamics are affine in w, so the Euler step (002 eq. (5), (9)) is
x_{k+1} = f(x_k, u_k) + g(x_k, u_k) w_k exactly, and the measurement (12) is
y_k = h(x_k, u_k) + b_k + d(x_k, u_k) w_k + e_k with h = [a_x, a_y, ψ̇] at
nominal stiffness. Kernels are written once for one state and looped over
particles by the callers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.io.vehicle import Vehicle

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

# State layout x = [v_x, v_y, ψ̇].
VX, VY, YAW_RATE = 0, 1, 2
N_STATE = 3
# Measurement layout y = [a_x, a_y, ψ̇].
M_AX, M_AY, M_YAW_RATE = 0, 1, 2
N_MEAS = 3
# Stiffness-deviation layout w = [ΔC^x (driven axle), ΔC_f^y, ΔC_r^y].
W_CX, W_CYF, W_CYR = 0, 1, 2
N_W = 3
# Input layout u = [δ, ω_f, ω_r, T_s].
U_DELTA, U_OMEGA_F, U_OMEGA_R, U_DT = 0, 1, 2, 3
N_INPUT = 4
# Parameter vector layout.
(P_M, P_IZ, P_LF, P_LR, P_RW, P_CXF, P_CXR, P_CYF, P_CYR, P_KXF, P_KXR, P_TXF, P_TXR, P_VMIN,
 P_DRAG, P_INV_M, P_INV_IZ) = range(17)
N_PARAM = 17

STIFFNESS_NAMES: tuple[str, str, str, str] = ("cx_f", "cx_r", "cy_f", "cy_r")
"""Axle-total stiffness names in the order of ``P_CXF`` … ``P_CYR`` and the log spec."""


@dataclass(frozen=True)
class SingleTrackParams:
    """Parameters of the single-track estimation model (SI).

    Attributes:
        mass: kg. yaw_inertia: kg m². lf, lr: CG to axle, m. wheel_radius: m.
        nominal: nominal axle-total stiffness C_n (002 eq. (7)) as
            (cx_f, cx_r in N per unit slip ratio, cy_f, cy_r in N/rad).
        drivetrain: "fwd" | "rwd" | "awd"; selects which longitudinal deviation
            w[W_CX] stands for (see the module docstring).
        v_min: m/s, lower bound of v_x in the slip denominators.
        drag: N s²/m², aerodynamic drag coefficient ½ ρ C_d A; the drag force
            −drag · v_x|v_x| enters eq. (1a) (002 Assumption 4 neglects it).
    """

    mass: float
    yaw_inertia: float
    lf: float
    lr: float
    wheel_radius: float
    nominal: tuple[float, float, float, float]
    drivetrain: str = "fwd"
    v_min: float = 1.0
    drag: float = 0.0

    def __post_init__(self) -> None:
        for name in ("mass", "yaw_inertia", "lf", "lr", "wheel_radius", "v_min"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"SingleTrackParams.{name} = {value} must be finite and > 0")
        if not (math.isfinite(self.drag) and self.drag >= 0):
            raise ValueError(f"SingleTrackParams.drag = {self.drag} must be finite and >= 0")
        if len(self.nominal) != 4 or not all(math.isfinite(c) and c > 0 for c in self.nominal):
            raise ValueError(f"SingleTrackParams.nominal = {self.nominal} must be four positive "
                             "stiffness values (cx_f, cx_r, cy_f, cy_r)")
        if self.drivetrain not in ("fwd", "rwd", "awd"):
            raise ValueError(f"SingleTrackParams.drivetrain = {self.drivetrain!r}; use fwd, rwd or awd")

    @classmethod
    def from_vehicle(cls, vehicle: Vehicle, nominal: tuple[float, float, float, float],
                     v_min: float = 1.0) -> SingleTrackParams:
        """Geometry and inertia from ``vehicle.body``, drag from ``vehicle.stated_aerodynamics``."""
        b, a = vehicle.body, vehicle.stated_aerodynamics
        return cls(mass=b.mass, yaw_inertia=b.yaw_inertia, lf=b.lf, lr=b.lr,
                   wheel_radius=b.wheel_radius, nominal=nominal, drivetrain=b.drivetrain,
                   v_min=v_min, drag=0.5 * a.air_density * a.drag_area)

    @property
    def longitudinal_split(self) -> tuple[float, float, float, float]:
        """(κ_f, κ_r, τ_f, τ_r): ΔC_f^x = κ_f w_x + τ_f w_yf and ΔC_r^x = κ_r w_x + τ_r w_yr.

        The undriven axle follows the driven axle's relative change (module docstring):
        τ_f = τ_r = 0 and κ = C_n^x(undriven)/C_n^x(driven) for it."""
        cxf, cxr, _, _ = self.nominal
        if self.drivetrain == "rwd":
            return cxf / cxr, 1.0, 0.0, 0.0
        return 1.0, cxr / cxf, 0.0, 0.0

    @property
    def longitudinal_name(self) -> str:
        """Log name of the estimated longitudinal stiffness: cx_f (FWD, AWD) or cx_r (RWD)."""
        return "cx_r" if self.drivetrain == "rwd" else "cx_f"

    def pack(self) -> np.ndarray:
        """The kernel parameter vector (indices ``P_*``)."""
        p = np.zeros(N_PARAM)
        p[P_M] = self.mass
        p[P_IZ] = self.yaw_inertia
        p[P_LF] = self.lf
        p[P_LR] = self.lr
        p[P_RW] = self.wheel_radius
        p[P_CXF], p[P_CXR], p[P_CYF], p[P_CYR] = self.nominal
        p[P_KXF], p[P_KXR], p[P_TXF], p[P_TXR] = self.longitudinal_split
        p[P_VMIN] = self.v_min
        p[P_DRAG] = self.drag
        p[P_INV_M] = 1.0 / self.mass
        p[P_INV_IZ] = 1.0 / self.yaw_inertia
        return p

    def deviation_to_axles(self, w: np.ndarray) -> np.ndarray:
        """Axle-total stiffness C_n + ΔC (002 eq. (7)) for deviations ``w`` (..., 3) → (..., 4)."""
        w = np.asarray(w, dtype=float)
        kf, kr, tf, tr = self.longitudinal_split
        cxf, cxr, cyf, cyr = self.nominal
        return np.stack([cxf + kf * w[..., W_CX] + tf * w[..., W_CYF],
                         cxr + kr * w[..., W_CX] + tr * w[..., W_CYR],
                         cyf + w[..., W_CYF], cyr + w[..., W_CYR]], axis=-1)

    def axles_to_deviation(self, c: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`deviation_to_axles` on the estimated components, (..., 4) → (..., 3)."""
        c = np.asarray(c, dtype=float)
        cxf, cxr, cyf, cyr = self.nominal
        wx = c[..., 1] - cxr if self.drivetrain == "rwd" else c[..., 0] - cxf
        # the tied component is implied by w_x and not inverted
        return np.stack([wx, c[..., 2] - cyf, c[..., 3] - cyr], axis=-1)


def roll_gradient(vehicle: Vehicle) -> float:
    """Steady-state roll gradient c_φ = φ/a_y in rad per m/s² from the suspension.

    Roll moment balance about the roll axis, pendulum term included:
    K_φ φ = m (h − h_rc)(a_y + g φ), so c_φ = m (h − h_rc)/(K_φ − m g (h − h_rc)).
    The measured lateral specific force of a body-fixed IMU is a_y(1 + c_φ g)
    (002 Sec. II-A, after eq. (10)).
    """
    b, s = vehicle.body, vehicle.suspension
    arm = b.mass * (b.cg_height - b.roll_center_height)
    return arm / (s.roll_stiffness - arm * G)


def pitch_gradient(vehicle: Vehicle) -> float:
    """Steady-state pitch gradient c_θ = −θ/a_x in rad per m/s² (θ > 0 nose down).

    K_θ θ = −m (h − h_pc)(a_x − g θ), so c_θ = m (h − h_pc)/(K_θ − m g (h − h_pc)) and
    a body-fixed accelerometer reads a_x(1 + c_θ g). 002 compensates roll only;
    pitch is the same effect on a_x and is compensated alike.
    """
    b, s = vehicle.body, vehicle.suspension
    arm = b.mass * (b.cg_height - s.pitch_center_height)
    return arm / (s.pitch_stiffness - arm * G)


@njit(**_JIT)
def slips(vx: float, vy: float, r: float, delta: float, omega_f: float, omega_r: float,
          p: np.ndarray) -> tuple[float, float, float, float]:
    """Axle slip ratios and slip angles, 002 eq. (3)–(4) (sign of eq. (3) fixed, see module).

    Returns:
        (λ_f, λ_r, α_f, α_r): slip ratios (traction > 0) and slip angles in rad
        (α > 0 gives a force to the left).
    """
    vmin = p[P_VMIN]
    vxg = vx if vx > vmin else vmin
    rw_f = p[P_RW] * omega_f
    rw_r = p[P_RW] * omega_r
    lam_f = (rw_f - vx) / max(rw_f, vxg)
    lam_r = (rw_r - vx) / max(rw_r, vxg)
    inv_v = 1.0 / vxg
    alpha_f = delta - (vy + p[P_LF] * r) * inv_v
    alpha_r = (p[P_LR] * r - vy) * inv_v
    return lam_f, lam_r, alpha_f, alpha_r


@njit(**_JIT)
def terms(vx: float, vy: float, r: float, delta: float, sin_d: float, cos_d: float,
          omega_f: float, omega_r: float, ts: float, p: np.ndarray) -> tuple[
              float, float, float, float, float, float, float, float, float, float, float, float,
              float, float]:
    """The model at one state as scalars: the single place where eq. (1)–(4), (9), (12) are coded.

    Args:
        vx, vy, r: state. delta: road-wheel angle δ, rad (``sin_d``, ``cos_d`` its sine and
            cosine, computed once per step by callers that loop over particles).
        omega_f, omega_r: axle-mean wheel speeds, rad/s. ts: step length T_s, s.
        p: parameter vector (``P_*``).

    Returns:
        (f_vx, f_vy, f_r, a_x, a_y, d_x_x, d_x_yf, d_x_yr, d_y_x, d_y_yf, d_y_yr, g_r_x, g_r_yf,
        g_r_yr): the Euler step f at nominal stiffness (eq. (9)); the accelerations h at
        nominal stiffness (eq. (12)); the accelerometer rows of d = ∂[a_x, a_y]/∂w (the
        yaw-rate row is zero); and the yaw-rate row of g = T_s ∂ẋ/∂w. The v_x and v_y rows
        of g are T_s times the a_x and a_y rows of d.
    """
    lam_f, lam_r, alpha_f, alpha_r = slips(vx, vy, r, delta, omega_f, omega_r, p)
    inv_m = p[P_INV_M]
    inv_i = p[P_INV_IZ]
    lf = p[P_LF]
    lr = p[P_LR]
    ffx = p[P_CXF] * lam_f
    frx = p[P_CXR] * lam_r
    ffy = p[P_CYF] * alpha_f
    fry = p[P_CYR] * alpha_r
    ax = (ffx * cos_d - ffy * sin_d + frx - p[P_DRAG] * vx * abs(vx)) * inv_m   # (1a) + drag
    ay = (ffy * cos_d + fry + ffx * sin_d) * inv_m                      # (1b)
    rdot = (lf * (ffy * cos_d + ffx * sin_d) - lr * fry) * inv_i        # (1c)
    # Forces are linear in C (eq. (2)), so these are exact sensitivities to w:
    # ∂F_f^x/∂w = λ_f [κ_f, τ_f, 0], ∂F_r^x/∂w = λ_r [κ_r, 0, τ_r], ∂F_f^y/∂w = [0, α_f, 0], …
    fx_x = p[P_KXF] * lam_f
    fx_yf = p[P_TXF] * lam_f
    rx_x = p[P_KXR] * lam_r
    rx_yr = p[P_TXR] * lam_r
    d_x_x = (fx_x * cos_d + rx_x) * inv_m
    d_x_yf = (fx_yf * cos_d - alpha_f * sin_d) * inv_m
    d_x_yr = rx_yr * inv_m
    d_y_x = fx_x * sin_d * inv_m
    d_y_yf = (alpha_f * cos_d + fx_yf * sin_d) * inv_m
    d_y_yr = alpha_r * inv_m
    g_r_x = ts * lf * fx_x * sin_d * inv_i
    g_r_yf = ts * lf * (alpha_f * cos_d + fx_yf * sin_d) * inv_i
    g_r_yr = -ts * lr * alpha_r * inv_i
    return (vx + ts * (ax + vy * r), vy + ts * (ay - vx * r), r + ts * rdot, ax, ay,
            d_x_x, d_x_yf, d_x_yr, d_y_x, d_y_yf, d_y_yr, g_r_x, g_r_yf, g_r_yr)


@njit(**_JIT)
def model_terms(x: np.ndarray, u: np.ndarray, p: np.ndarray, f: np.ndarray, g: np.ndarray,
                h: np.ndarray, d: np.ndarray) -> None:
    """Array form of :func:`terms`: f, g, h, d of 002 eq. (9), (12) at one state.

    Args:
        x: state (3,). u: input (4,) [δ, ω_f, ω_r, T_s]. p: parameter vector.
        f: (3,) ← x + T_s ẋ(x, u; C_n), the Euler step at nominal stiffness.
        g: (3, 3) ← T_s ∂ẋ/∂w (eq. (10) generalised to all three components).
        h: (3,) ← [a_x, a_y, ψ̇] at nominal stiffness.
        d: (3, 3) ← ∂h/∂w = [∂a_x/∂w; ∂a_y/∂w; 0] (see the module note on eq. (12)).
    """
    delta = u[U_DELTA]
    ts = u[U_DT]
    (f0, f1, f2, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, grx, gryf, gryr) = terms(
        x[VX], x[VY], x[YAW_RATE], delta, math.sin(delta), math.cos(delta), u[U_OMEGA_F],
        u[U_OMEGA_R], ts, p)
    f[VX] = f0
    f[VY] = f1
    f[YAW_RATE] = f2
    h[M_AX] = ax
    h[M_AY] = ay
    h[M_YAW_RATE] = x[YAW_RATE]
    d[M_AX, W_CX] = dxx
    d[M_AX, W_CYF] = dxyf
    d[M_AX, W_CYR] = dxyr
    d[M_AY, W_CX] = dyx
    d[M_AY, W_CYF] = dyyf
    d[M_AY, W_CYR] = dyyr
    d[M_YAW_RATE, W_CX] = 0.0
    d[M_YAW_RATE, W_CYF] = 0.0
    d[M_YAW_RATE, W_CYR] = 0.0
    for j in range(N_W):
        g[VX, j] = ts * d[M_AX, j]
        g[VY, j] = ts * d[M_AY, j]
    g[YAW_RATE, W_CX] = grx
    g[YAW_RATE, W_CYF] = gryf
    g[YAW_RATE, W_CYR] = gryr


@njit(**_JIT)
def simulate_kernel(x0: np.ndarray, u: np.ndarray, w: np.ndarray, p: np.ndarray,
                    x_out: np.ndarray, y_out: np.ndarray) -> None:
    """Run the model forward: x_{k+1} = f + g w_k, y_k = h + d w_k (002 eq. (9), (12), no noise).

    Args:
        x0: (3,) initial state. u: (K, 4) inputs. w: (K, 3) stiffness deviations.
        x_out: (K, 3) ← x_k. y_out: (K, 3) ← noise- and bias-free y_k.
    """
    f = np.empty(N_STATE)
    g = np.empty((N_STATE, N_W))
    h = np.empty(N_MEAS)
    d = np.empty((N_MEAS, N_W))
    x = x0.copy()
    for k in range(u.shape[0]):
        model_terms(x, u[k], p, f, g, h, d)
        for i in range(N_STATE):
            x_out[k, i] = x[i]
        for i in range(N_MEAS):
            s = h[i]
            for j in range(N_W):
                s += d[i, j] * w[k, j]
            y_out[k, i] = s
        for i in range(N_STATE):
            s = f[i]
            for j in range(N_W):
                s += g[i, j] * w[k, j]
            x[i] = s


def simulate(x0: np.ndarray, u: np.ndarray, w: np.ndarray,
             params: SingleTrackParams) -> tuple[np.ndarray, np.ndarray]:
    """Trajectory and noise-free measurements of the estimation model (for tests and 002 Sec. VI-A data).

    Args:
        x0: (3,) initial [v_x, v_y, ψ̇]. u: (K, 4) inputs [δ, ω_f, ω_r, T_s].
        w: (K, 3) stiffness deviations from ``params.nominal`` per step.

    Returns:
        (x, y): states (K, 3) and measurements (K, 3) [a_x, a_y, ψ̇].
    """
    u = np.ascontiguousarray(u, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if u.ndim != 2 or u.shape[1] != N_INPUT or w.shape != (u.shape[0], N_W):
        raise ValueError(f"u must be (K, {N_INPUT}) and w (K, {N_W}); got {u.shape} and {w.shape}")
    x = np.empty((u.shape[0], N_STATE))
    y = np.empty((u.shape[0], N_MEAS))
    simulate_kernel(np.asarray(x0, dtype=float), u, w, params.pack(), x, y)
    return x, y
