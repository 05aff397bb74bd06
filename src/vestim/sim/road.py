"""Road description: friction μ and a stiffness factor per wheel, grade and bank.

Friction and stiffness factor are tabulated per wheel (columns fl, fr, rl, rr)
over time (s) or over travelled distance (m); over distance, each wheel meets a
change when *it* reaches it (front wheels first). Grade and bank are tabulated
over distance. Tables are piecewise linear and held beyond their ends; a step
change is a ramp of ``RAMP_S`` seconds or ``RAMP_M`` metres, short against the
dynamics yet continuous for the integrator.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

RAMP_S = 0.05
"""Duration of a time-based surface change, s."""
RAMP_M = 0.5
"""Length of a distance-based surface change, m (about a tire contact patch and a half)."""

MU_MIN = 0.05
"""Smallest friction coefficient accepted (polished wet ice is about 0.05)."""


def _check_mu(mu: float, what: str) -> float:
    if not MU_MIN <= mu <= 1.5:
        raise ValueError(f"{what} = {mu} must lie in [{MU_MIN}, 1.5]")
    return float(mu)


@dataclass(frozen=True)
class Road:
    """Friction, stiffness factor, grade and bank seen by the four wheels.

    Attributes:
        knots: (K,) strictly increasing times (s) or distances (m).
        mu: (K, 4) peak friction coefficient per wheel.
        stiffness: (K, 4) factor on tire stiffness per wheel (1 = the tire's own).
        by_distance: whether ``knots`` are distances.
        geo_knots: (G,) distances (m) for grade and bank.
        grade: (G,) road grade, rad (> 0 climbing).
        bank: (G,) road bank, rad (> 0 lifts the left side).
    """

    knots: np.ndarray
    mu: np.ndarray
    stiffness: np.ndarray
    by_distance: bool = False
    geo_knots: np.ndarray = field(default_factory=lambda: np.array([0.0]))
    grade: np.ndarray = field(default_factory=lambda: np.array([0.0]))
    bank: np.ndarray = field(default_factory=lambda: np.array([0.0]))

    def __post_init__(self) -> None:
        knots = np.asarray(self.knots, dtype=float)
        if knots.ndim != 1 or knots.size == 0 or np.any(np.diff(knots) <= 0):
            raise ValueError("road knots must be a non-empty, strictly increasing 1-D array")
        for name in ("mu", "stiffness"):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (knots.size, 4):
                raise ValueError(f"road {name} must have shape ({knots.size}, 4), got {arr.shape}")
        if np.any(np.asarray(self.mu) < MU_MIN) or np.any(np.asarray(self.mu) > 1.5):
            raise ValueError(f"road mu must lie in [{MU_MIN}, 1.5]")
        if np.any(np.asarray(self.stiffness) <= 0):
            raise ValueError("road stiffness factors must be > 0")
        geo = np.asarray(self.geo_knots, dtype=float)
        if geo.ndim != 1 or np.any(np.diff(geo) <= 0):
            raise ValueError("road geo_knots must be strictly increasing")
        for name in ("grade", "bank"):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != geo.shape or np.any(np.abs(arr) > 0.35):
                raise ValueError(f"road {name} must match geo_knots and stay within ±0.35 rad")

    # ------------------------------------------------------------ constructors
    @classmethod
    def uniform(cls, mu: float, stiffness: float = 1.0) -> Road:
        """The same surface under every wheel for the whole run."""
        _check_mu(mu, "mu")
        return cls(np.array([0.0]), np.full((1, 4), mu), np.full((1, 4), stiffness))

    @classmethod
    def split(cls, mu_left: float, mu_right: float) -> Road:
        """Split-μ: left wheels (fl, rl) on ``mu_left``, right wheels (fr, rr) on ``mu_right``."""
        _check_mu(mu_left, "mu_left")
        _check_mu(mu_right, "mu_right")
        row = np.array([[mu_left, mu_right, mu_left, mu_right]])
        return cls(np.array([0.0]), row, np.ones((1, 4)))

    @classmethod
    def transition(cls, mu_from: float, mu_to: float, at: float, *, by_distance: bool = False,
                   stiffness_from: float = 1.0, stiffness_to: float = 1.0) -> Road:
        """Every wheel changes from one surface to another at time ``at`` s (or distance m)."""
        _check_mu(mu_from, "mu_from")
        _check_mu(mu_to, "mu_to")
        ramp = RAMP_M if by_distance else RAMP_S
        knots = np.array([at, at + ramp])
        mu = np.array([[mu_from] * 4, [mu_to] * 4])
        stiff = np.array([[stiffness_from] * 4, [stiffness_to] * 4])
        return cls(knots, mu, stiff, by_distance=by_distance)

    def with_geometry(self, grade: float = 0.0, bank: float = 0.0) -> Road:
        """Copy with a constant grade and bank (rad)."""
        return Road(self.knots, self.mu, self.stiffness, self.by_distance,
                    np.array([0.0]), np.array([float(grade)]), np.array([float(bank)]))
