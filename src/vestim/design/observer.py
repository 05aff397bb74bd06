"""Design and certification of the LuGre corner velocity observers of 001/004.

- :func:`design_lpv`: wheel-speed-scheduled gains L1(|ω|), L2(|ω|) for the
  longitudinal (001 eq. (24)) and lateral (001 eq. (38)) observers from the LPV
  synthesis LMIs (001 eq. (30)–(32), 004 eq. (26)–(35)); returns a
  :class:`~vestim.estimators.velocity.lpv_gains.GainSchedule` (write it with ``save_gains``).
- :func:`check_design`: certify given gains (a schedule, a gains file, or by
  default the constant gains of 001 Sec. IV) for a vehicle: affine quadratic
  stability (001 eq. (28)) and the H∞ performance γ (004 eq. (24)–(25)), each
  verified independently on a fine wheel-speed grid.

Disturbance and performance channels follow 001 eq. (25) and 004 eq. (27):
w = [Ω_z, Ω_a] (m/s, m/s²) enters through B_e = I − L C′ and the performance
output is the relative-velocity error z = e_vr (m/s), so γ bounds
‖e_vr‖₂ / ‖Ω‖₂.

Why a pole radius by default: for every gain, the DC gain from Ω_z to e_vr at
ω = 0 is exactly 1 (the friction term is indistinguishable from a slip-velocity
offset in steady state), so γ ≥ 1 for any observer and minimising γ alone is
degenerate — the solver then returns arbitrary, often huge gains. Bounding the
frozen error-dynamics poles by |λ| ≤ 2/T_s (400 1/s at the 200 Hz of 001's
logs; a forward-Euler step stays stable there) makes the problem well posed;
set ``pole_radius=None`` to reproduce the unconstrained problem of the papers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vestim.design.analysis import affine_quadratic_stability, check_lyapunov, hinf_performance
from vestim.design.lmi import LMIResult, LPVSystem, ParameterBox, verification_grid
from vestim.design.papers import REFERENCE_GAINS
from vestim.design.synthesis import (
    Objective,
    ObserverPlant,
    SynthesisResult,
    synthesize_observer,
)
from vestim.estimators.velocity.lpv_gains import (
    DIRECTIONS,
    GainSchedule,
    ObserverGains,
    StoredCertificate,
    load_gains,
)
from vestim.io.vehicle import Vehicle, load_vehicle
from vestim.models.lpv import (
    LPVState,
    LuGreAxis,
    affine_error_dynamics,
    affine_output_matrices,
    affine_state_matrices,
    lateral_axis,
    longitudinal_axis,
    measurement_disturbance_matrix,
)

__all__ = [
    "Certificate",
    "DesignSpec",
    "DirectionCertificate",
    "check_design",
    "design_lpv",
    "lugre_observer_plant",
]

PERFORMANCE_OUTPUT = np.array([[0.0, 1.0]])
"""z = e_vr (004 eq. (27): y_e = [0 1] e)."""


@dataclass(frozen=True)
class DesignSpec:
    """Options of :func:`design_lpv` and :func:`check_design`.

    Attributes:
        omega_max: |ω| range [0, omega_max], rad/s (001 Sec. IV-A1: 180).
        omega_dot_max: |ω̇| bound, rad/s² (001: 800; 004: 600).
        n_grid: wheel-speed grid the synthesis LMIs are imposed on (and the
            stored schedule's table); verification uses a 10× finer grid.
        degree: polynomial degree of P(ω) and χ(ω) (004 used affine ones).
        pole_radius: bound on |λ| of the frozen error dynamics, 1/s, or None.
        slack: relative γ slack traded for a robust certificate (second stage).
        weights: scaling of the disturbances (Ω_z, Ω_a) in w.
        objective: second stage of the synthesis ("decay": fastest guaranteed
            decay within the γ slack; "margin": most robust LMI margin only).
    """

    omega_max: float = 180.0
    omega_dot_max: float = 800.0
    n_grid: int = 37
    degree: int = 1
    pole_radius: float | None = 400.0
    slack: float = 0.02
    weights: tuple[float, float] = (1.0, 1.0)
    objective: Objective = "decay"

    def __post_init__(self) -> None:
        if not self.omega_max > 0 or not self.omega_dot_max >= 0:
            raise ValueError("DesignSpec: omega_max must be > 0 and omega_dot_max >= 0")
        if self.n_grid < 2 or self.degree < 0:
            raise ValueError("DesignSpec: n_grid must be >= 2 and degree >= 0")
        if self.pole_radius is not None and not self.pole_radius > 0:
            raise ValueError("DesignSpec: pole_radius must be > 0 or None")
        if self.slack < 0 or any(not w > 0 for w in self.weights):
            raise ValueError("DesignSpec: slack must be >= 0 and weights > 0")
        if self.objective not in ("decay", "margin"):
            raise ValueError(f"DesignSpec: objective {self.objective!r}; use 'decay' or 'margin'")

    @property
    def box(self) -> ParameterBox:
        """ρ = |ω| ∈ [0, omega_max], |ρ̇| ≤ omega_dot_max."""
        return ParameterBox(0.0, self.omega_max, self.omega_dot_max)


def _vehicle(vehicle: Vehicle | str | Path) -> Vehicle:
    return vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)


def _axis(vehicle: Vehicle, direction: str) -> LuGreAxis:
    if direction == "longitudinal":
        return longitudinal_axis(vehicle)
    if direction == "lateral":
        return lateral_axis(vehicle)
    raise ValueError(f"direction {direction!r}: use one of {', '.join(DIRECTIONS)}")


def lugre_observer_plant(axis: LuGreAxis, weights: tuple[float, float] = (1.0, 1.0)) -> ObserverPlant:
    """The corner model as an :class:`ObserverPlant` in ρ = |ω|.

    A(ρ) = A0 + ρA1 (001 eq. (22)), C_y(ρ) = C0 + ρC1 (001 eq. (23)), B = W,
    F = C′W with C′ = [σ1, 0] (μ = C_y x + σ1Ω_z), H = [0, 1], W = diag(weights).
    """
    a0, a1 = affine_state_matrices(axis)
    c0, c1 = affine_output_matrices(axis)
    w = np.diag(np.asarray(weights, float))
    return ObserverPlant(a=np.stack([a0, a1]), cy=np.stack([c0, c1]), b=w,
                         f=measurement_disturbance_matrix(axis) @ w, h=PERFORMANCE_OUTPUT)


def _table_system(plant: ObserverPlant, gains: ObserverGains) -> LPVSystem:
    return plant.closed_loop(gains.gain_matrix)


def design_direction(axis: LuGreAxis, spec: DesignSpec) -> tuple[ObserverGains, SynthesisResult]:
    """Synthesise one direction's schedule and verify its tabulated (interpolated) form."""
    plant = lugre_observer_plant(axis, spec.weights)
    box = spec.box
    syn = synthesize_observer(plant, box, degree=spec.degree, n_grid=spec.n_grid,
                              pole_radius=spec.pole_radius, slack=spec.slack,
                              objective=spec.objective)
    cert = syn.certificate
    if syn.chi is None or cert.lyapunov is None or cert.gamma is None:
        raise ValueError(f"LPV synthesis infeasible: {cert.summary()}")
    omega = box.grid(spec.n_grid)
    lg = syn.gain(omega)
    table = ObserverGains(omega, lg[:, LPVState.Z, 0], lg[:, LPVState.VR, 0], axis)
    sched = check_lyapunov(_table_system(plant, table), box, cert.lyapunov, gamma=cert.gamma,
                           n_verify=verification_grid(box, spec.n_grid).size,
                           problem="tabulated schedule")
    stored = StoredCertificate(
        gamma=cert.gamma, gamma_opt=float(cert.gamma_opt or cert.gamma), verified=cert.verified,
        schedule_verified=sched.verified, min_eig=min(cert.min_eig, sched.min_eig),
        omega_max=spec.omega_max, omega_dot_max=spec.omega_dot_max,
        pole_radius=spec.pole_radius, lyapunov=cert.lyapunov, chi=syn.chi)
    return ObserverGains(omega, table.l1, table.l2, axis, stored), syn


def design_lpv(vehicle: Vehicle | str | Path, spec: DesignSpec | None = None, *,
               directions: tuple[str, ...] = DIRECTIONS) -> GainSchedule:
    """Design wheel-speed-scheduled observer gains for a vehicle (001 eq. (30)–(32)).

    Args:
        vehicle: a :class:`Vehicle`, a vehicle TOML path or a built-in name.
        spec: design options (default :class:`DesignSpec`: |ω| ≤ 180 rad/s,
            |ω̇| ≤ 800 rad/s², 37-point grid, affine P and χ, pole radius 400 1/s).
        directions: which observers to design ("longitudinal", "lateral").
    Returns:
        The schedule with its certificates; ``schedule.save_gains(path)`` writes it.
    Raises:
        ValueError: if a synthesis is infeasible (the message carries the certificate).
    """
    veh = _vehicle(vehicle)
    spec = spec or DesignSpec()
    dirs = {d: design_direction(_axis(veh, d), spec)[0] for d in directions}
    return GainSchedule(vehicle=veh.name, directions=dirs, omega_dot_max=spec.omega_dot_max)


# ------------------------------------------------------------------------ certificate
@dataclass(frozen=True)
class DirectionCertificate:
    """Certificates of one observer direction."""

    direction: str
    source: str
    box: ParameterBox
    stability: tuple[LMIResult, ...]
    hinf: tuple[LMIResult, ...]
    stored: LMIResult | None = None
    notes: tuple[str, ...] = ()

    @property
    def stable(self) -> bool:
        """Affine quadratic stability verified by at least one method."""
        return any(r.verified for r in self.stability)

    @property
    def gamma(self) -> float | None:
        """Smallest verified γ, or None."""
        gs = [r.gamma for r in self.hinf if r.verified and r.gamma is not None]
        return min(gs) if gs else None

    @property
    def verified(self) -> bool:
        """Stable and a finite γ verified."""
        return self.stable and self.gamma is not None


@dataclass(frozen=True)
class Certificate:
    """Result of :func:`check_design` for one vehicle."""

    vehicle: str
    directions: dict[str, DirectionCertificate] = field(default_factory=dict)

    @property
    def verified(self) -> bool:
        """Every direction verified."""
        return all(d.verified for d in self.directions.values())

    @property
    def gamma(self) -> dict[str, float | None]:
        """Verified γ per direction."""
        return {k: d.gamma for k, d in self.directions.items()}

    def summary(self) -> str:
        """The certificate as text: per direction the verdicts, margins and γ."""
        lines = [f"observer design check for vehicle {self.vehicle!r}: "
                 f"{'VERIFIED' if self.verified else 'NOT VERIFIED'}"]
        for name, d in self.directions.items():
            g = d.gamma
            lines.append(f"\n== {name}: {d.source}")
            lines.append(f"   |omega| <= {d.box.upper:g} rad/s, |omega_dot| <= {d.box.rate:g} "
                         f"rad/s^2; stable: {d.stable}; gamma: "
                         f"{'none verified' if g is None else f'{g:.6g}'}")
            for r in (*d.stability, *d.hinf):
                lines.append("   " + r.summary().replace("\n", "\n   "))
            if d.stored is not None:
                lines.append("   stored certificate: " + d.stored.summary().replace("\n", "\n   "))
            lines += [f"   note: {n}" for n in d.notes]
        return "\n".join(lines)


def _check_direction(direction: str, axis: LuGreAxis, gains: ObserverGains | None,
                     spec: DesignSpec, source: str) -> DirectionCertificate:
    plant = lugre_observer_plant(axis, spec.weights)
    notes: list[str] = []
    stored_result = None
    if gains is None:
        l1, l2 = REFERENCE_GAINS[direction]
        box = spec.box
        a0, a1, be = affine_error_dynamics(l1, l2, axis)
        system = LPVSystem.from_affine(a0, a1, be @ plant.b, None, PERFORMANCE_OUTPUT)
        methods: tuple[str, ...] = ("vertex", "grid")
    else:
        c = gains.certificate
        box = ParameterBox(0.0, c.omega_max if c else spec.omega_max,
                           c.omega_dot_max if c else spec.omega_dot_max)
        if gains.axis != axis:
            notes.append(f"gains were designed for {gains.axis}, the vehicle has {axis}; "
                         "certified against the vehicle")
        if gains.omega[-1] < box.upper:
            notes.append(f"table ends at {gains.omega[-1]:g} rad/s < {box.upper:g}; "
                         "gains are held constant beyond")
        system = _table_system(plant, gains)
        methods = ("grid",)
        if c is not None:
            stored_result = check_lyapunov(system, box, c.lyapunov, gamma=c.gamma,
                                           n_verify=verification_grid(box, spec.n_grid).size,
                                           problem=f"stored certificate (gamma = {c.gamma:.6g})")
    stab: list[LMIResult] = []
    hinf: list[LMIResult] = []
    for m in methods:
        s = affine_quadratic_stability(system, box, method=m,  # type: ignore[arg-type]
                                       n_grid=spec.n_grid)
        h = hinf_performance(system, box, method=m, n_grid=spec.n_grid)  # type: ignore[arg-type]
        stab.append(s)
        hinf.append(h)
        if s.verified and h.verified:
            break
    return DirectionCertificate(direction, source, box, tuple(stab), tuple(hinf), stored_result,
                                tuple(notes))


def check_design(vehicle: Vehicle | str | Path, gains: GainSchedule | str | Path | None = None,
                 *, spec: DesignSpec | None = None) -> Certificate:
    """Certify observer gains for a vehicle: affine quadratic stability and H∞ γ.

    Args:
        vehicle: a :class:`Vehicle`, a vehicle TOML path or a built-in name.
        gains: a :class:`GainSchedule`, a gains TOML path, or None for the constant
            gains of 001 Sec. IV (L1x = 0.68, L2x = 183.1; L1y = 1.11, L2y = 16.7).
        spec: operating region and grid (default :class:`DesignSpec`); a stored
            certificate's ω_max and ω̇_max take precedence for its direction.
    Returns:
        :class:`Certificate`; ``summary()`` prints it. Constant gains are tested with
        the papers' vertex + multi-convexity test, then (if that fails) on a grid;
        tabulated gains (interpolated as an observer would) on a grid. A stored
        certificate is re-verified with its own P(ω) and γ.
    """
    veh = _vehicle(vehicle)
    spec = spec or DesignSpec()
    if gains is None:
        dirs = {d: _check_direction(d, _axis(veh, d), None, spec,
                                    "constant gains L1 = {:g}, L2 = {:g} (001 Sec. IV)".format(
                                        *REFERENCE_GAINS[d]))
                for d in DIRECTIONS}
        return Certificate(veh.name, dirs)
    sched = gains if isinstance(gains, GainSchedule) else load_gains(gains)
    src = "gain schedule" if isinstance(gains, GainSchedule) else f"gains file {str(gains)!r}"
    dirs = {d: _check_direction(d, _axis(veh, d), g, spec, f"{src} (designed for {sched.vehicle!r})")
            for d, g in sched.directions.items()}
    return Certificate(veh.name, dirs)
