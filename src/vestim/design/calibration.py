"""Offline calibration of the LuGre tire parameters from ground truth (NOT an estimator).

:func:`fit_lugre` fits the steady state of the combined-slip average lumped LuGre
model (004 eq. (6)–(7) with ż = 0, :func:`vestim.models.tire.lugre_steady_state`)

    z_i = v_ri / (σ0i‖v_r‖/(θ g(‖v_r‖)) + κ_i R|ω|),   μ_i = σ0i z_i + σ2i v_ri,   i ∈ {x, y}

to (relative velocity, normalised force) pairs by nonlinear least squares. It is a
calibration tool: given a simulator log it reads the ``ref_`` channels (wheel-centre
velocities, slip ratios, tire and normal forces), which no estimator may do. Its
purpose is to quantify how far the nominal ``[tire]`` table is from the tire a
plant actually has — e.g. the Magic Formula plant, whose small-slip stiffness
(kx = 20 per unit slip ratio) is a quarter of the nominal LuGre tire's σ0x/κx ≈ 76 —
and to rerun the corner observers with fitted parameters.

What is identifiable from steady state: σ0, σ2, κ per direction and the friction
curve θ·μ_s, θ·μ_c, V_s (θ is fixed to 1, so the fitted μ_s, μ_c are those of the
road the data were taken on); σ1 (rubber damping) and the Stribeck exponent α act
only in transients or weakly and are kept at their nominal values.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.io.log import road_wheel_angles
from vestim.io.vehicle import LuGreTire, Vehicle
from vestim.models.kinematics import to_tire_frame
from vestim.models.tire import lugre_steady_state

FIT_X = ("sigma0_x", "sigma2_x", "kappa_x")
FIT_Y = ("sigma0_y", "sigma2_y", "kappa_y")
FIT_FRICTION = ("mu_s", "mu_c", "v_s")


@dataclass(frozen=True)
class LuGreSamples:
    """(relative velocity, normalised force) samples of tires, flattened over time and corners.

    Attributes:
        vrx: R ω − v_xt, m/s.   vry: −v_yt, m/s.   omega_r: R|ω|, m/s.
        mu_x, mu_y: F_x/F_z, F_y/F_z.
    """

    vrx: np.ndarray
    vry: np.ndarray
    omega_r: np.ndarray
    mu_x: np.ndarray
    mu_y: np.ndarray

    def __post_init__(self) -> None:
        arrs = [np.asarray(getattr(self, n), dtype=float).ravel()
                for n in ("vrx", "vry", "omega_r", "mu_x", "mu_y")]
        if len({a.size for a in arrs}) != 1:
            raise ValueError("LuGreSamples: vrx, vry, omega_r, mu_x, mu_y must have equal sizes")
        for name, a in zip(("vrx", "vry", "omega_r", "mu_x", "mu_y"), arrs, strict=True):
            object.__setattr__(self, name, a)

    def __len__(self) -> int:
        return int(self.vrx.size)

    def select(self, mask: np.ndarray) -> LuGreSamples:
        return LuGreSamples(self.vrx[mask], self.vry[mask], self.omega_r[mask], self.mu_x[mask],
                            self.mu_y[mask])


def samples_from_log(log: pd.DataFrame, vehicle: Vehicle, min_speed: float = 1.0,
                     min_load: float = 500.0) -> LuGreSamples:
    """Ground-truth tire samples of a simulator log (reads ``ref_`` channels: calibration only).

    R ω is recovered exactly from ``ref_slip_ratio_*`` and the tire-frame speed
    (the measured wheel speeds are noisy): R ω = v_xt (1 + λ) when R|ω| ≤ |v_xt|, else
    v_xt / (1 − λ) (spec definition of λ). Samples with both speeds below
    ``min_speed`` m/s or a load below ``min_load`` N are dropped.
    """
    need = [f"ref_{q}_{c}" for q in ("vx", "vy", "fx", "fy", "fz", "slip_ratio") for c in CORNERS]
    missing = [c for c in need if c not in log.columns]
    if missing:
        raise LogFormatError(f"fit_lugre needs ground-truth column(s) {', '.join(missing[:4])}"
                             f"{' …' if len(missing) > 4 else ''} (a simulator log)")
    cols = {q: log[[f"ref_{q}_{c}" for c in CORNERS]].to_numpy(dtype=float)
            for q in ("vx", "vy", "fx", "fy", "fz", "slip_ratio")}
    delta = np.zeros((len(log), 4))
    delta[:, :2] = road_wheel_angles(log, vehicle.body.steering_ratio)
    vxt, vyt = to_tire_frame(cols["vx"], cols["vy"], delta)
    lam = cols["slip_ratio"]
    with np.errstate(divide="ignore", invalid="ignore"):
        rw_a = vxt * (1.0 + lam)  # |Rω| ≤ |v_xt|: λ = (Rω − v)/v
        rw_b = vxt / (1.0 - lam)  # |Rω| > |v_xt|: λ = (Rω − v)/(Rω)
    rw = np.where(np.abs(rw_a) <= np.abs(vxt) + 1e-12, rw_a, rw_b)
    fz = cols["fz"]
    ok = ((np.maximum(np.abs(rw), np.abs(vxt)) > min_speed) & (fz > min_load) & np.isfinite(rw))
    with np.errstate(divide="ignore", invalid="ignore"):
        mux = cols["fx"] / fz
        muy = cols["fy"] / fz
    return LuGreSamples(rw - vxt, -vyt, np.abs(rw), mux, muy).select(ok.ravel())


def _as_samples(data: pd.DataFrame | LuGreSamples | Sequence[pd.DataFrame],
                vehicle: Vehicle) -> LuGreSamples:
    if isinstance(data, LuGreSamples):
        return data
    if isinstance(data, pd.DataFrame):
        return samples_from_log(data, vehicle)
    parts = [samples_from_log(d, vehicle) for d in data]
    return LuGreSamples(*(np.concatenate([getattr(p, n) for p in parts])
                          for n in ("vrx", "vry", "omega_r", "mu_x", "mu_y")))


def fit_lugre(data: pd.DataFrame | LuGreSamples | Sequence[pd.DataFrame], vehicle: Vehicle, *,
              directions: tuple[str, ...] = ("x", "y"), max_samples: int = 20_000,
              prior_weight: float = 0.01, rng: np.random.Generator | None = None) -> LuGreTire:
    """Least-squares fit of the steady-state LuGre curves to ground-truth tire samples.

    Calibration, not estimation: reads ``ref_`` channels when given logs.

    Args:
        data: a simulator log, several logs, or :class:`LuGreSamples`.
        vehicle: supplies R and the nominal ``[tire]`` table (start point, and the
            values kept: σ1, α, and the other direction's parameters).
        directions: "x", "y" or both; σ0, σ2, κ of each listed direction are fitted,
            with the shared friction curve μ_s, μ_c, V_s (θ = 1).
        max_samples: random subsample size (uniform, ``rng``; default seeded 0).
        prior_weight: weight of a ridge term pulling each log-parameter toward its nominal
            value, per √(number of residuals): moving a parameter by a factor e costs as
            much as raising the RMS force residual by ``prior_weight``. Without it the
            directions the data cannot see drift freely — in small slip only σ0/κ and
            the small-slip stiffness σ0/κ + σ2R|ω| are identifiable, not σ0 and κ apart.
        rng: generator for the subsample.

    Returns:
        The nominal :class:`LuGreTire` with the fitted fields replaced.

    Raises:
        ValueError: unknown direction, or fewer than 50 usable samples.
    """
    bad = [d for d in directions if d not in ("x", "y")]
    if bad or not directions:
        raise ValueError(f"directions {directions!r}: use 'x', 'y' or both")
    s = _as_samples(data, vehicle)
    ok = np.isfinite(s.vrx) & np.isfinite(s.vry) & np.isfinite(s.mu_x) & np.isfinite(s.mu_y)
    s = s.select(ok)
    if len(s) < 50:
        raise ValueError(f"fit_lugre: only {len(s)} usable samples; need >= 50")
    if len(s) > max_samples:
        gen = rng if rng is not None else np.random.default_rng(0)
        s = s.select(np.sort(gen.choice(len(s), max_samples, replace=False)))
    names = [*(FIT_X if "x" in directions else ()), *(FIT_Y if "y" in directions else ()),
             *FIT_FRICTION]
    nominal = vehicle.tire
    # Every parameter in log space (σ2 may be tiny); μ_s as μ_c plus a positive excess
    # so that the fitted tire keeps μ_c ≤ μ_s.
    start = {n: getattr(nominal, n) for n in names}
    start["mu_s"] = nominal.mu_s - nominal.mu_c
    p0 = np.log(np.array([max(start[n], 1e-6) for n in names]))

    def tire_of(p: np.ndarray) -> LuGreTire:
        v = dict(zip(names, np.exp(p).tolist(), strict=True))
        v["mu_s"] = v["mu_c"] + v["mu_s"]
        return replace(nominal, **v)

    def residual(p: np.ndarray) -> np.ndarray:
        tire = tire_of(p)
        mux, muy = lugre_steady_state(s.vrx, s.vry, s.omega_r, 1.0, tire)
        parts = []
        if "x" in directions:
            parts.append(mux - s.mu_x)
        if "y" in directions:
            parts.append(muy - s.mu_y)
        data = np.nan_to_num(np.concatenate(parts), nan=1e3)
        return np.concatenate([data, ridge * (p - p0)])

    ridge = prior_weight * np.sqrt(len(s) * len(directions))
    sol = least_squares(residual, p0, method="trf", x_scale=1.0, max_nfev=200)
    return tire_of(sol.x)
