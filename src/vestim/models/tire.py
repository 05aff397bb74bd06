"""Tire models: combined-slip average lumped LuGre and a combined-slip Magic Formula.

Pure functions, compiled with Numba, written once for scalars so that the same
code serves the simulator, sigma points and particles (loop over them in the
caller's kernel). Units are SI; normalised forces μ = F/Fz are dimensionless.

Sign conventions (docs/format.md): tire frame x forward along
the wheel heading, y left. Relative (slip) velocities of the LuGre model are
``vrx = R·ω − vxt`` and ``vry = −vyt`` (001 text after eq. (21)), so traction
(R·ω > vxt) gives Fx > 0 and a tire sliding to the left (vyt > 0) gets Fy < 0.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from scipy.optimize import brentq

from vestim.io.vehicle import LuGreTire, MagicFormula

_JIT: dict[str, Any] = {"cache": True, "fastmath": False, "error_model": "numpy"}


# --------------------------------------------------------------------------- LuGre
@njit(**_JIT)
def lugre_g(vr_norm: float, mu_s: float, mu_c: float, v_s: float, alpha: float) -> float:
    """Stribeck function g(v_r) (004 text after eq. (6), isotropic case).

    With μcx = μcy = μc and μsx = μsy = μs (one value of each in the vehicle
    file), ‖M_c² v_r‖/‖M_c v_r‖ = μc‖v_r‖ / ‖v_r‖ = μc, and 004's combined-slip
    g reduces to the pure-slip form of 001: g = μc + (μs − μc)·exp(−|‖v_r‖/V_s|^α).
    """
    return mu_c + (mu_s - mu_c) * math.exp(-((vr_norm / v_s) ** alpha))


@njit(**_JIT)
def lugre_zdot(
    zx: float, zy: float, vrx: float, vry: float, omega_r_abs: float, theta: float,
    sigma0_x: float, sigma0_y: float, kappa_x: float, kappa_y: float,
    mu_s: float, mu_c: float, v_s: float, alpha: float,
) -> tuple[float, float]:
    """Internal-deflection dynamics of the combined-slip average lumped LuGre model.

    004 eq. (6) with the road classification factor θ (000 eq. (16)):
    ż_i = v_ri − σ0i‖v_r‖/(θ g(v_r)) z_i − κ_i R|ω| z_i,   i ∈ {x, y}.
    004 writes C0i = ‖M_c² v_r‖σ0i/(g μci²); with isotropic μc that is σ0i‖v_r‖/g,
    and θ divides it as in 000/004's friction term σ0|v_r|/(θ g) z.

    Args:
        zx, zy: internal deflections, m.
        vrx, vry: relative velocities, m/s.
        omega_r_abs: R·|ω|, m/s.
        theta: road classification factor (0, 1]; see :func:`lugre_theta_for_mu`.
    Returns:
        (ż_x, ż_y) in m/s.
    """
    vn = math.sqrt(vrx * vrx + vry * vry)
    friction = vn / (theta * lugre_g(vn, mu_s, mu_c, v_s, alpha))
    dzx = vrx - sigma0_x * friction * zx - kappa_x * omega_r_abs * zx
    dzy = vry - sigma0_y * friction * zy - kappa_y * omega_r_abs * zy
    return dzx, dzy


@njit(**_JIT)
def lugre_rates(vrx: float, vry: float, omega_r_abs: float, theta: float,
                sigma0_x: float, sigma0_y: float, kappa_x: float, kappa_y: float,
                mu_s: float, mu_c: float, v_s: float, alpha: float) -> tuple[float, float]:
    """Decay rates a_i (1/s) of ż_i = v_ri − a_i z_i in 004 eq. (6): σ0i‖v_r‖/(θ g) + κ_i R|ω|."""
    vn = math.sqrt(vrx * vrx + vry * vry)
    friction = vn / (theta * lugre_g(vn, mu_s, mu_c, v_s, alpha))
    return sigma0_x * friction + kappa_x * omega_r_abs, sigma0_y * friction + kappa_y * omega_r_abs


def lugre_steady_state(
    vrx: np.ndarray | float, vry: np.ndarray | float, omega_r_abs: np.ndarray | float,
    theta: float, tire: LuGreTire,
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form steady state (ż = 0) of 004 eq. (6)–(7): normalised forces (μx, μy).

    z_i = v_ri / (σ0i‖v_r‖/(θ g) + κ_i R|ω|) and μ_i = σ0i z_i + σ2i v_ri.
    Vectorised over NumPy arrays; used by tests and by :func:`lugre_theta_for_mu`.
    """
    vrx = np.asarray(vrx, dtype=float)
    vry = np.asarray(vry, dtype=float)
    vn = np.hypot(vrx, vry)
    g = tire.mu_c + (tire.mu_s - tire.mu_c) * np.exp(-((vn / tire.v_s) ** tire.alpha))
    friction = vn / (theta * g)
    with np.errstate(invalid="ignore", divide="ignore"):
        zx = np.where(vrx == 0, 0.0, vrx / (tire.sigma0_x * friction + tire.kappa_x * omega_r_abs))
        zy = np.where(vry == 0, 0.0, vry / (tire.sigma0_y * friction + tire.kappa_y * omega_r_abs))
    return tire.sigma0_x * zx + tire.sigma2_x * vrx, tire.sigma0_y * zy + tire.sigma2_y * vry


def lugre_peak_mu(theta: float, tire: LuGreTire, speed: float = 20.0) -> float:
    """Peak of the steady-state pure traction curve μx(λ) at wheel-centre speed ``speed`` (m/s)."""
    lam = np.linspace(1e-4, 0.5, 4000)
    omega_r = speed / (1.0 - lam)  # traction: λ = (Rω − v)/(Rω)
    mux, _ = lugre_steady_state(omega_r - speed, 0.0, omega_r, theta, tire)
    return float(np.max(mux))


def lugre_theta_for_mu(mu: float, tire: LuGreTire, speed: float = 20.0) -> float:
    """Road classification factor θ whose steady-state traction peak at ``speed`` equals μ.

    The papers give θ only as a range (0.1 < θ < 0.98, icy to dry, 004 Sec. II-A;
    0.1 ≤ θ ≤ 0.97, 000 Sec. IV) and never tie it to a friction coefficient. The
    simulator needs one road friction μ for both tire plants (the Magic Formula's
    peak is exactly μ·Fz), so we define θ(μ) by that same physical meaning: the
    peak of the steady-state LuGre traction curve (slip ratio ≤ 0.5) at 20 m/s
    equals μ. For the SUV's tire (μs = 1.2, μc = 0.8) μ = 0.3 gives θ ≈ 0.30 and
    dry μ = 1.0 gives θ ≈ 1.10; the viscous term σ2·v_r makes very low-μ curves
    rise slowly with slip, so there the "peak" is the value at slip ratio 0.5.
    """
    if not mu > 0.0:
        raise ValueError(f"road friction mu = {mu} must be > 0")
    hi = 10.0
    if lugre_peak_mu(hi, tire, speed) < mu:
        raise ValueError(f"road friction mu = {mu} is beyond what this LuGre tire can reach")
    return float(brentq(lambda th: lugre_peak_mu(th, tire, speed) - mu, 1e-4, hi, xtol=1e-10))



@njit(**_JIT)
def lugre_small_slip_stiffness(
    fz: float, omega_r_abs: float, scale: float,
    sigma0_x: float, sigma2_x: float, kappa_x: float,
    sigma0_y: float, sigma2_y: float, kappa_y: float,
) -> tuple[float, float]:
    """Small-slip stiffness of one LuGre tire: (C_x in N per unit slip ratio, C_y in N/rad).

    Linearising the steady state of 004 eq. (6)–(7) at v_r = 0 (the ‖v_r‖
    friction term is second order): μx = (σ0x/κx + σ2x R|ω|) λ with v_rx = λ R|ω|,
    and μy = −(σ0y/κy + σ2y R|ω|) α with v_ry = −v_yt ≈ −α R|ω|. It does not
    depend on θ: road friction bends the LuGre curve only through the ‖v_r‖ term.
    ``scale`` is the road stiffness factor multiplying σ0.
    """
    cx = fz * (scale * sigma0_x / kappa_x + sigma2_x * omega_r_abs)
    cy = fz * (scale * sigma0_y / kappa_y + sigma2_y * omega_r_abs)
    return cx, cy


# ------------------------------------------------------------------- Magic Formula
@njit(**_JIT)
def _mf_shape(bx: float, c: float, e: float) -> float:
    return math.sin(c * math.atan(bx - e * (bx - math.atan(bx))))


@njit(**_JIT)
def mf_stiffness(fz: float, scale: float, fz0: float, kx: float, kx_load: float,
                 ky1: float, ky2: float) -> tuple[float, float]:
    """Small-slip stiffness of one tire: (K_x in N per unit slip ratio, K_y in N/rad).

    K_x = Fz·kx·(1 + kx_load·dfz), dfz = (Fz − Fz0)/Fz0 (PAC2002 pKx1/pKx3 in linear form);
    K_y = ky1·Fz0·sin(2 atan(Fz/(ky2 Fz0))) (PAC2002 pKy1, pKy2). ``scale`` multiplies both.
    """
    dfz = (fz - fz0) / fz0
    kx_n = kx * max(1.0 + kx_load * dfz, 0.2)
    x = fz / (ky2 * fz0)
    return scale * fz * kx_n, scale * ky1 * fz0 * 2.0 * x / (1.0 + x * x)


@njit(**_JIT)
def magic_formula(
    kappa: float, alpha: float, fz: float, mu: float, scale: float,
    fz0: float, c_x: float, e_x: float, kx: float, kx_load: float,
    c_y: float, e_y: float, ky1: float, ky2: float,
    rbx1: float, rbx2: float, rby1: float, rby2: float,
) -> tuple[float, float]:
    """Combined-slip Magic Formula with load dependence: tire-frame forces (Fx, Fy) in N.

    Pure slip: F = D sin(C atan(Bs − E(Bs − atan(Bs)))), peak D = μ·Fz exactly,
    B = K/(C D) with the load-dependent stiffness of :func:`mf_stiffness`.
    Combined slip by the PAC2002 cosine weighting functions:
    G_xα = cos(atan(B_xα α)), B_xα = rbx1 cos(atan(rbx2 κ)), and
    G_yκ = cos(atan(B_yκ κ)), B_yκ = rby1 cos(atan(rby2 α)).

    Args:
        kappa: slip ratio (traction > 0).
        alpha: slip angle in rad in the spec's sign, atan(v_yt/v_xt); Fy opposes it.
        fz: normal load, N (clipped at 0: a lifted wheel carries no force).
        mu: road friction coefficient (peak), > 0.
        scale: road stiffness factor multiplying K_x and K_y.
    """
    if fz <= 0.0:
        return 0.0, 0.0
    dfz = (fz - fz0) / fz0
    kx_n = scale * kx * max(1.0 + kx_load * dfz, 0.2)  # K_x / Fz
    x = fz / (ky2 * fz0)
    ky_n = scale * ky1 * 2.0 / (ky2 * (1.0 + x * x))  # K_y / Fz
    d = mu * fz
    bx = kx_n / (c_x * mu)  # K/(C D) with the Fz cancelled: finite as Fz → 0
    by = ky_n / (c_y * mu)
    fx0 = d * _mf_shape(bx * kappa, c_x, e_x)
    fy0 = -d * _mf_shape(by * alpha, c_y, e_y)
    g_xa = math.cos(math.atan(rbx1 * math.cos(math.atan(rbx2 * kappa)) * alpha))
    g_yk = math.cos(math.atan(rby1 * math.cos(math.atan(rby2 * alpha)) * kappa))
    return g_xa * fx0, g_yk * fy0


def magic_formula_params(mf: MagicFormula) -> tuple[float, ...]:
    """The ``[magic_formula]`` table as the positional tail of :func:`magic_formula`."""
    return (mf.fz0, mf.c_x, mf.e_x, mf.kx, mf.kx_load, mf.c_y, mf.e_y, mf.ky1, mf.ky2,
            mf.rbx1, mf.rbx2, mf.rby1, mf.rby2)
