"""LPV corner models of the LuGre-based velocity observers (the one place they live).

One tire direction q ∈ {x, y} of one corner, scheduled by the wheel speed ω.
State ``x = [z̄_q, v_rq]`` (index with :class:`LPVState`):

- ``z̄_q``  average lumped LuGre internal deflection, m;
- ``v_rq`` relative (slip) velocity, m/s: ``v_rx = R·ω − v_xt`` (longitudinal),
  ``v_ry = −v_yt`` (lateral), 001 text after eq. (19).

Dynamics, 001 eq. (20)–(22), (37) and 004 eq. (8)–(12)::

    ż̄_q  = v_rq − κ_q R|ω| z̄_q + Ω_zq        (Ω_zq: the road-friction term σ0|v_r| z̄/(θ g), bounded)
    v̇_rq = u_q + Ω_aq                        (u_x = R ω̇ − v̇_xt,  u_y = −v̇_yt)

Output: the normalised tire force μ_q = F_q/F_z (LuGre eq. (19) of 001 / (7) of 004)::

    μ_q = σ0 z̄ + σ1 ż̄ + σ2 v_r = C x + C′ẋ              004 eq. (14), C = [σ0, σ2], C′ = [σ1, 0]
        = C_q(ω) x + σ1 Ω_zq,  C_q(ω) = C + C′A(ω)     001 eq. (23), (36)

so ``C_q(ω) = [σ0 − σ1 κ R|ω|, σ1 + σ2]``. The scheduling parameter is ρ = |ω|
(rad/s): the LuGre term is κR|ω| (004 eq. (8)), and 001/004 write A(ω) with
ω ≥ 0 (001 after eq. (25): "ω : R≥0 → Sp"). ``|d|ω|/dt| = |ω̇|``, so the rate
bound carries over unchanged. Every matrix is affine in ρ: ``A(ρ) = A0 + ρ A1``.

Two observer forms, both used in the papers, give the same error dynamics:

- *innovation form* (001 eq. (24)): ``x̂˙ = A x̂ + B u + L (μ − C_q(ω) x̂)``;
  error ``ė = (A − L C_q) e + (I − L C′) Ω``  (001 eq. (25)).
- *output-derivative form* (004 eq. (10)–(13)): ``μ̂ = C x̂ + C′ x̂˙``;
  error ``ė = (I + L̃C′)⁻¹(A − L̃C) e + (I + L̃C′)⁻¹ Ω``  (004 eq. (16)).

They coincide for ``L = L̃ / (1 + σ1 L̃1)`` (:func:`output_derivative_to_innovation`).
This is the relation "Lp1 = L1/(1+L1 S1); Lp2 = L2/(1+L1 S1)" left in the text of
001 Fig. 3–4, so those figures plot innovation-form gains.

Deviations from the printed equations (extraction checked against a derivation
from the LuGre equations 004 eq. (6)–(8); the finite-difference tests in
``tests/models/test_lpv.py`` confirm the derivation):

- 001 eq. (26): the (1,2) entry of A0 is ``1 − L1 p1`` (the text shows ``−L1 p1``).
- 001 eq. (25)/(30): ``B_e = I − L B_e1`` with ``B_e1 = [σ1 0]`` (the text writes ``I + L B_e1``
  under the matrix that is printed with the minus sign).
- 004 eq. (20): the (1,1) entry of a1 is ``−κR/(1 + L1σ1)`` (the text shows ``−κR``).

Units: σ0 in 1/m, σ1 and σ2 in s/m, κ in 1/m, R in m, ω in rad/s. Gains of the
innovation form: L1 in m/s, L2 in m/s² (per unit of normalised force).
All functions are pure and accept arrays of ω (leading batch axes).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vestim.io.vehicle import Vehicle

__all__ = [
    "KalmanState",
    "LPVState",
    "LuGreAxis",
    "affine_error_dynamics",
    "affine_output_matrices",
    "affine_state_matrices",
    "error_dynamics",
    "innovation_to_output_derivative",
    "input_matrix",
    "kalman_model",
    "lateral_axis",
    "longitudinal_axis",
    "measurement_disturbance_matrix",
    "output_derivative_to_innovation",
    "output_matrices_derivative_form",
    "output_matrix",
    "state_matrix",
]

GainForm = Literal["innovation", "output_derivative"]
FArray = NDArray[np.float64]


class LPVState(IntEnum):
    """Layout of the two-state corner model (001 eq. (22), 004 eq. (12))."""

    Z = 0
    """z̄_q, LuGre internal deflection, m."""
    VR = 1
    """v_rq, relative velocity, m/s."""


class KalmanState(IntEnum):
    """Layout of the three-state time-varying Kalman model of 000 eq. (19)."""

    Z = 0
    VR = 1
    ZDOT = 2
    """ż̄_x, deflection rate, m/s."""


@dataclass(frozen=True)
class LuGreAxis:
    """LuGre parameters of one tire direction and the wheel radius.

    Attributes:
        sigma0: rubber stiffness σ0q, 1/m.
        sigma1: rubber damping σ1q, s/m.
        sigma2: relative viscous damping σ2q, s/m.
        kappa: load-distribution factor κq, 1/m.
        wheel_radius: effective rolling radius R, m.
    """

    sigma0: float
    sigma1: float
    sigma2: float
    kappa: float
    wheel_radius: float

    def __post_init__(self) -> None:
        for name in ("sigma0", "kappa", "wheel_radius"):
            if not getattr(self, name) > 0:
                raise ValueError(f"LuGreAxis.{name} = {getattr(self, name)} must be > 0")
        for name in ("sigma1", "sigma2"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"LuGreAxis.{name} = {getattr(self, name)} must be >= 0")

    @property
    def decay_per_omega(self) -> float:
        """κR in m/m = rad⁻¹: the deflection decay rate per rad/s of wheel speed."""
        return self.kappa * self.wheel_radius


def longitudinal_axis(vehicle: Vehicle) -> LuGreAxis:
    """The longitudinal LuGre parameters (σ0x, σ1x, σ2x, κx) and R of a vehicle."""
    t = vehicle.tire
    return LuGreAxis(t.sigma0_x, t.sigma1_x, t.sigma2_x, t.kappa_x, vehicle.body.wheel_radius)


def lateral_axis(vehicle: Vehicle) -> LuGreAxis:
    """The lateral LuGre parameters (σ0y, σ1y, σ2y, κy) and R of a vehicle."""
    t = vehicle.tire
    return LuGreAxis(t.sigma0_y, t.sigma1_y, t.sigma2_y, t.kappa_y, vehicle.body.wheel_radius)


def _rho(omega: ArrayLike) -> FArray:
    return np.abs(np.asarray(omega, dtype=float))


def affine_state_matrices(axis: LuGreAxis) -> tuple[FArray, FArray]:
    """(A0, A1) with A(ω) = A0 + |ω| A1; 001 eq. (22), 004 eq. (12).

    A0 = [[0, 1], [0, 0]] (1/s), A1 = [[−κR, 0], [0, 0]] (rad⁻¹).
    """
    a0 = np.array([[0.0, 1.0], [0.0, 0.0]])
    a1 = np.array([[-axis.decay_per_omega, 0.0], [0.0, 0.0]])
    return a0, a1


def state_matrix(omega: ArrayLike, axis: LuGreAxis) -> FArray:
    """A(ω), shape (..., 2, 2), 1/s: 001 eq. (22) and (37), 004 eq. (12)."""
    a0, a1 = affine_state_matrices(axis)
    rho = _rho(omega)[..., None, None]
    return a0 + rho * a1


def input_matrix() -> FArray:
    """B = [0, 1]ᵀ, shape (2, 1): the input u (m/s²) drives v̇_r (001 eq. (22))."""
    return np.array([[0.0], [1.0]])


def affine_output_matrices(axis: LuGreAxis) -> tuple[FArray, FArray]:
    """(C0, C1) with C_q(ω) = C0 + |ω| C1, shapes (1, 2); 001 eq. (23).

    C0 = [σ0, σ1 + σ2] (1/m, s/m), C1 = [−σ1 κ R, 0].
    """
    c0 = np.array([[axis.sigma0, axis.sigma1 + axis.sigma2]])
    c1 = np.array([[-axis.sigma1 * axis.decay_per_omega, 0.0]])
    return c0, c1


def output_matrix(omega: ArrayLike, axis: LuGreAxis) -> FArray:
    """C_q(ω) = [σ0 − σ1κR|ω|, σ1 + σ2], shape (..., 1, 2); 001 eq. (23), (36)."""
    c0, c1 = affine_output_matrices(axis)
    return c0 + _rho(omega)[..., None, None] * c1


def output_matrices_derivative_form(axis: LuGreAxis) -> tuple[FArray, FArray]:
    """(C, C′) of 004 eq. (14): μ = C x + C′ ẋ with C = [σ0, σ2], C′ = [σ1, 0]; shapes (1, 2)."""
    return (np.array([[axis.sigma0, axis.sigma2]]), np.array([[axis.sigma1, 0.0]]))


def measurement_disturbance_matrix(axis: LuGreAxis) -> FArray:
    """C′ = [σ1, 0], shape (1, 2): μ = C_q(ω)x + C′Ω, so Ω_z also corrupts the output (001 eq. (23))."""
    return np.array([[axis.sigma1, 0.0]])


def innovation_to_output_derivative(l1: ArrayLike, l2: ArrayLike,
                                    sigma1: float) -> tuple[FArray, FArray]:
    """Gains of the innovation form (001 eq. (24)) → output-derivative form (004 eq. (10)).

    L̃ = L / (1 − σ1 L1). Raises ``ValueError`` where σ1 L1 = 1, at which the
    innovation-form gain has no output-derivative equivalent.
    """
    l1a = np.asarray(l1, dtype=float)
    l2a = np.asarray(l2, dtype=float)
    den = 1.0 - sigma1 * l1a
    if np.any(np.abs(den) < 1e-12):
        raise ValueError("σ1·L1 = 1: this innovation gain has no output-derivative form")
    return l1a / den, l2a / den


def output_derivative_to_innovation(l1: ArrayLike, l2: ArrayLike,
                                    sigma1: float) -> tuple[FArray, FArray]:
    """Gains of the output-derivative form (004 eq. (10)) → innovation form (001 eq. (24)).

    L = (I + L̃C′)⁻¹ L̃ = L̃ / (1 + σ1 L̃1); the "Lp" of 001 Fig. 3–4.
    """
    l1a = np.asarray(l1, dtype=float)
    l2a = np.asarray(l2, dtype=float)
    den = 1.0 + sigma1 * l1a
    if np.any(np.abs(den) < 1e-12):
        raise ValueError("1 + σ1·L1 = 0: I + L C′ is singular (004 eq. (16))")
    return l1a / den, l2a / den


def _gain_column(l1: ArrayLike, l2: ArrayLike, axis: LuGreAxis,
                 form: GainForm) -> FArray:
    if form == "innovation":
        g1, g2 = np.asarray(l1, dtype=float), np.asarray(l2, dtype=float)
    elif form == "output_derivative":
        g1, g2 = output_derivative_to_innovation(l1, l2, axis.sigma1)
    else:
        raise ValueError(f"gain form {form!r}: use 'innovation' or 'output_derivative'")
    g1, g2 = np.broadcast_arrays(g1, g2)
    return np.stack([g1, g2], axis=-1)[..., None]  # (..., 2, 1)


def error_dynamics(omega: ArrayLike, l1: ArrayLike, l2: ArrayLike, axis: LuGreAxis,
                   form: GainForm = "innovation") -> tuple[FArray, FArray]:
    """Observer error dynamics ė = A_e(ω) e + B_e Ω for gains L = [L1, L2]ᵀ.

    Innovation form: A_e = A(ω) − L C_q(ω), B_e = I − L C′ (001 eq. (25), (39)).
    Output-derivative form (gains L̃ of 004 eq. (10)): A_e = (I + L̃C′)⁻¹(A − L̃C),
    B_e = (I + L̃C′)⁻¹ (004 eq. (16)); computed through the equivalent innovation gain.

    Args:
        omega: wheel speed(s), rad/s (the sign is ignored).
        l1, l2: gains, broadcastable with ``omega`` (constant or scheduled).
        axis: LuGre parameters of the direction.
        form: which observer form the gains belong to.
    Returns:
        (A_e, B_e), shapes (..., 2, 2) and (..., 2, 2); Ω = [Ω_z (m/s), Ω_a (m/s²)].
    """
    lcol = _gain_column(l1, l2, axis, form)
    a = state_matrix(omega, axis)
    c = output_matrix(omega, axis)
    ae = a - lcol @ c
    be = np.eye(2) - lcol @ measurement_disturbance_matrix(axis)
    ae, be = np.broadcast_arrays(ae, be)
    return np.array(ae), np.array(be)


def affine_error_dynamics(l1: float, l2: float, axis: LuGreAxis,
                          form: GainForm = "innovation") -> tuple[FArray, FArray, FArray]:
    """(a0, a1, B_e) with A_e(ω) = a0 + |ω| a1 for constant gains.

    Innovation form, 001 eq. (26) (with the (1,2) entry of A0 corrected)::

        a0 = [[−L1σ0, 1 − L1 p1], [−L2σ0, −L2 p1]],  a1 = κR [[L1σ1 − 1, 0], [L2σ1, 0]],
        p1 = σ1 + σ2.

    Output-derivative form, 004 eq. (20) (with a1's (1,1) entry corrected to
    −κR/(1 + L1σ1)).
    """
    e0, be = error_dynamics(0.0, l1, l2, axis, form)
    e1, _ = error_dynamics(1.0, l1, l2, axis, form)
    return e0, e1 - e0, be


def kalman_model(omega: ArrayLike, omega_dot: ArrayLike,
                 axis: LuGreAxis) -> tuple[FArray, FArray, FArray]:
    """Three-state time-varying model of the Kalman velocity observer, 000 eq. (19).

    State ``[z̄_x, v_rx, ż̄_x]`` (:class:`KalmanState`). Writing 000's
    ``M ẋ = Ā x + [0,1,0]ᵀ u`` with ``M = [[1,0,0],[0,1,0],[0,−1,1]]`` explicitly
    (differentiate ż̄ = v_r − κR|ω| z̄)::

        A = [[−κR|ω|, 1, 0], [0, 0, 0], [−κR d|ω|/dt, 0, −κR|ω|]],  B = [0, 1, 1]ᵀ,
        C = [σ0, σ2, σ1]   (μ = σ0 z̄ + σ2 v_r + σ1 ż̄).

    Args:
        omega: wheel speed, rad/s; omega_dot: its time derivative, rad/s²
            (d|ω|/dt = sign(ω)·ω̇ is used).
    Returns:
        (A, B, C) with shapes (..., 3, 3), (3, 1), (1, 3).
    """
    w = np.asarray(omega, dtype=float)
    wd = np.asarray(omega_dot, dtype=float)
    rho = np.abs(w)
    rho_dot = np.where(w < 0, -wd, wd)
    rho, rho_dot = np.broadcast_arrays(rho, rho_dot)
    kr = axis.decay_per_omega
    a = np.zeros((*rho.shape, 3, 3))
    a[..., KalmanState.Z, KalmanState.Z] = -kr * rho
    a[..., KalmanState.Z, KalmanState.VR] = 1.0
    a[..., KalmanState.ZDOT, KalmanState.Z] = -kr * rho_dot
    a[..., KalmanState.ZDOT, KalmanState.ZDOT] = -kr * rho
    b = np.array([[0.0], [1.0], [1.0]])
    c = np.array([[axis.sigma0, axis.sigma2, axis.sigma1]])
    return a, b, c
