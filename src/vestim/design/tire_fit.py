"""LuGre tire values fitted to one drive log's MEASURED signals (no ground truth).

:func:`fit_lugre_from_log` runs the pipeline's reference filter and force stage on the
log's measured channels (every ``ref_`` column is dropped first), forms per-corner
tire samples

    v_rx = R ω − v̂_xt,   v_ry = −v̂_yt,   R|ω|,   μ_x = F̂_x/F̂_z,   μ_y = F̂_y/F̂_z

(ω: measured wheel speeds, lightly smoothed; v̂: the reference filter's wheel-centre
speeds in the tire frame; F̂: the force stage's estimates), and fits the steady state
of the combined-slip average lumped LuGre model (004 eq. (6)–(7) with ż = 0,
:func:`vestim.models.tire.lugre_steady_state`) to them by bounded least squares
(:func:`scipy.optimize.least_squares`, all parameters in log space).

Parameterisation (what a steady-state curve can tell apart):

* ``C_i = σ0i/κ_i`` (i = x, y), the small-slip stiffness per unit load
  (:func:`vestim.models.tire.lugre_small_slip_stiffness` at R|ω| → 0); any log with
  slip above the noise determines it;
* ``σ0i`` apart from κ_i: not in the steady state at all (transients only); kept nominal;
* ``σ2i``: the viscous term, σ2·R|ω| in the stiffness and σ2·v_r in sliding;
* ``μ_c``, ``μ_s``, ``V_s`` (Stribeck curve with θ = 1, so they are the road's of
  this log, as in :mod:`vestim.design.calibration`); α and σ1 (transient only)
  are never fitted.

"Excited" is decided from the data, per parameter: C_i and σ2i need ``min_near_limit``
small-slip samples (2e-3 ≤ |slip| ≤ 0.05) that carry force (|μ| ≥ 0.05); the friction
curve (μ_c, μ_s/μ_c, V_s; fitted from μ_x only) needs ``min_near_limit`` samples with |μ_x|
at least half the fitted friction level g(‖v_r‖) (where the LuGre curve μ = g·Cλ/(g + Cλ)
has bent to half its linear line); and every parameter needs a relative standard error
≤ ``max_rel_se`` from the Jacobian at the solution (SVD; residual variance inflated for
the ~0.1 s correlation of the force stage's errors) and must not sit on a bound. σ0i is
never identifiable from a steady state (σ0 z = v_r/(‖v_r‖/(θg) + R|ω|/C) holds σ0 only
in C). A parameter that fails keeps its nominal value; κ_i = σ0i,nominal / C_i carries a
fitted stiffness. Residuals are weighted by the effective variance σ_μ² + (∂μ/∂v_r)²σ_vr²
(σ_μ: the force stage's own σ; σ_vr: the wheel-speed noise measured from the log), the
errors-in-variables correction without which the noisy slip regressor attenuates C.

What the pipeline's corner observers use of the result: σ0, σ1, σ2, κ (x; and y for
the lateral LPV) — never μ_s, μ_c, V_s (000/001 treat the friction term as a bounded
disturbance). The reference filter's cornering-stiffness prior is σ0y/κy.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from vestim.constants import CORNERS
from vestim.estimators.velocity.reference import ReferenceParams
from vestim.io.vehicle import LuGreTire, Vehicle
from vestim.models.tire import lugre_peak_mu, lugre_steady_state

BOUNDS: dict[str, tuple[float, float]] = {
    "C_x": (1.0, 300.0),        # σ0x/κx, per unit slip ratio (PAC tires: ~10–30)
    "sigma0_x": (20.0, 5000.0),  # 1/m
    "sigma2_x": (1e-5, 0.05),    # s/m
    "C_y": (1.0, 300.0),        # σ0y/κy, per rad
    "sigma0_y": (10.0, 5000.0),
    "sigma2_y": (1e-5, 0.05),
    "mu_c": (0.03, 1.6),
    "ratio_s": (1.0001, 3.0),    # μ_s / μ_c
    "v_s": (0.05, 30.0),         # m/s
}
"""Physical bounds of the fitted quantities (log-space box of the least squares)."""

FRICTION = ("mu_c", "ratio_s", "v_s")
"""The friction curve g(v_r): only near-limit samples determine it."""


@dataclass(frozen=True)
class ParamFit:
    """One fitted quantity: nominal and final value, whether the log determined it, and why."""

    name: str
    nominal: float
    value: float
    excited: bool
    rel_se: float
    note: str


@dataclass(frozen=True)
class TireFitReport:
    """What :func:`fit_lugre_from_log` saw and decided.

    Attributes:
        params: one :class:`ParamFit` per quantity of :data:`BOUNDS` (``ratio_s`` = μ_s/μ_c,
            so a fitted friction level with an unexcited shape scales μ_s with μ_c).
        samples: tire samples used per direction.
        near_limit: samples beyond the linear region per direction (see the module text).
        slip_range: (min, max) slip ratio of the x samples against the reference filter.
        rms_nominal, rms_fit: RMS of μ residuals per direction with the nominal and the
            fitted tire; the nominal friction curve is scaled (θ) to the log's 99.5 %
            |μ| so the comparison is about shape, and so is the fitted tire's where its
            friction level was not excited (θ = 1 where it was).
    """

    params: tuple[ParamFit, ...]
    samples: dict[str, int]
    near_limit: dict[str, int]
    slip_range: tuple[float, float]
    rms_nominal: dict[str, float]
    rms_fit: dict[str, float]
    peak_mu: float

    def param(self, name: str) -> ParamFit:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)

    def excited(self, name: str) -> bool:
        return self.param(name).excited

    def summary(self) -> str:
        lines = [f"samples x {self.samples.get('x', 0)}, y {self.samples.get('y', 0)}; "
                 f"near-limit x {self.near_limit.get('x', 0)}, y {self.near_limit.get('y', 0)};"
                 f" slip ratio {self.slip_range[0]:+.3f} … {self.slip_range[1]:+.3f};"
                 f" fitted traction peak {self.peak_mu:.2f}"]
        for p in self.params:
            state = (f"fitted {p.value:.4g} (±{100 * p.rel_se:.1f} %)" if p.excited
                     else f"not excited ({p.note}), kept {p.value:.4g}")
            lines.append(f"  {p.name:9s} nominal {p.nominal:<8.4g} {state}")
        lines.append("  RMS μ residual nominal → fitted: " + ", ".join(
            f"{d} {self.rms_nominal[d]:.4f} → {self.rms_fit[d]:.4f}" for d in self.rms_fit))
        return "\n".join(lines)


@dataclass(frozen=True)
class _Samples:
    vrx: np.ndarray
    vry: np.ndarray
    omega_r: np.ndarray
    mu: np.ndarray  # the fitted direction's normalised force
    lam: np.ndarray  # slip (ratio for x, angle-like v_ry/R|ω| for y)
    sig_mu: np.ndarray  # the force stage's own 1σ of μ
    sig_vr: float  # 1σ of v_r from the wheel-speed noise (x; 0 for y), m/s

    def take(self, idx: np.ndarray) -> _Samples:
        return _Samples(self.vrx[idx], self.vry[idx], self.omega_r[idx], self.mu[idx],
                        self.lam[idx], self.sig_mu[idx], self.sig_vr)


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    """The log without any ground-truth (``ref_``) or private (``_``) column."""
    return log[[c for c in log.columns if not str(c).startswith(("ref_", "_"))]]


def _smooth(a: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average along axis 0 (edges: shorter windows); offline, zero phase."""
    if width <= 1:
        return a
    k = np.ones(width) / width
    num = np.apply_along_axis(lambda c: np.convolve(c, k, mode="same"), 0, a)
    den = np.convolve(np.ones(a.shape[0]), k, mode="same")[:, None]
    return np.asarray(num / den)


def tire_samples(log: pd.DataFrame, vehicle: Vehicle, *, min_speed: float = 1.5,
                 min_load: float = 500.0, smooth: int = 5) -> tuple[dict[str, _Samples], pd.DataFrame]:
    """Per-direction tire samples from the measured signals, and the pipeline estimate used.

    The pipeline runs with ``velocity="reference"`` (its F_x, F_z are the same as the
    default's: the force stage does not depend on the velocity stage), with the reference
    filter's slip model free of any stiffness (``slip_bias`` = 0, ``k_mu`` = 1): the default
    removes an expected slip μ_x/C from each wheel with a prior C, and a v̂ built on that
    prior would return it as the fitted stiffness.
    """
    from vestim.pipeline import Pipeline, PipelineConfig  # design → pipeline, used only here

    meas = _measured(log)
    free = ReferenceParams(k_mu=1.0, slip_bias=0.0)
    est = Pipeline(vehicle, PipelineConfig(velocity="reference", reference=free)).run(meas)
    radius = vehicle.body.wheel_radius
    omega = meas[[f"omega_{c}" for c in CORNERS]].to_numpy(dtype=float)
    rw = radius * _smooth(omega, smooth)
    # Wheel-speed noise from the data: MAD of the second difference (white noise: √6 σ).
    d2 = np.diff(omega, 2, axis=0)
    sig_w = float(np.median(np.abs(d2 - np.median(d2, axis=0)))) / 0.6745 / np.sqrt(6.0)
    sig_vr = radius * sig_w / np.sqrt(max(smooth, 1))
    vxt = est[[f"vxt_{c}" for c in CORNERS]].to_numpy(dtype=float)
    vyt = est[[f"vyt_{c}" for c in CORNERS]].to_numpy(dtype=float)
    fz = est[[f"fz_{c}" for c in CORNERS]].to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        mux = est[[f"fx_{c}" for c in CORNERS]].to_numpy(dtype=float) / fz
        muy = est[[f"fy_{c}" for c in CORNERS]].to_numpy(dtype=float) / fz
        sx = np.maximum(est[[f"sigma_fx_{c}" for c in CORNERS]].to_numpy(dtype=float) / fz,
                        0.003)
        sy = np.maximum(est[[f"sigma_fy_{c}" for c in CORNERS]].to_numpy(dtype=float) / fz,
                        0.003)
        lam = (rw - vxt) / np.maximum(np.abs(rw), np.abs(vxt))
        lat = -vyt / np.maximum(np.abs(rw), np.abs(vxt))
    ok = ((np.abs(rw) > min_speed) & (vxt > min_speed) & (fz > min_load)
          & np.isfinite(mux) & np.isfinite(muy) & np.isfinite(vyt) & np.isfinite(lam)
          & np.isfinite(sx) & np.isfinite(sy))
    out = {}
    for d, mu, s, sm, sv in (("x", mux, lam, sx, sig_vr), ("y", muy, lat, sy, 0.0)):
        out[d] = _Samples((rw - vxt)[ok], (-vyt)[ok], np.abs(rw)[ok], mu[ok], s[ok], sm[ok], sv)
    return out, est


def _tire_from(values: dict[str, float], nominal: LuGreTire) -> LuGreTire:
    v = dict(values)
    kw: dict[str, float] = {}
    for d in ("x", "y"):
        s0 = v[f"sigma0_{d}"]
        kw[f"sigma0_{d}"] = s0
        kw[f"kappa_{d}"] = s0 / v[f"C_{d}"]
        kw[f"sigma2_{d}"] = v[f"sigma2_{d}"]
    kw["mu_c"] = v["mu_c"]
    kw["mu_s"] = v["mu_c"] * v["ratio_s"]
    kw["v_s"] = v["v_s"]
    return replace(nominal, **kw)


def _nominal_values(tire: LuGreTire) -> dict[str, float]:
    return {"C_x": tire.sigma0_x / tire.kappa_x, "sigma0_x": tire.sigma0_x,
            "sigma2_x": tire.sigma2_x, "C_y": tire.sigma0_y / tire.kappa_y,
            "sigma0_y": tire.sigma0_y, "sigma2_y": tire.sigma2_y, "mu_c": tire.mu_c,
            "ratio_s": max(tire.mu_s / tire.mu_c, 1.0001), "v_s": tire.v_s}


def _model(tire: LuGreTire, s: _Samples, d: str) -> np.ndarray:
    mux, muy = lugre_steady_state(s.vrx, s.vry, s.omega_r, 1.0, tire)
    return np.asarray(mux if d == "x" else muy)


def _weighted_residual(tire: LuGreTire, s: _Samples, d: str) -> np.ndarray:
    """Effective-variance residual (μ_model − μ)/√(σ_μ² + (∂μ/∂v_r)² σ_vr²).

    The slip velocity is itself a noisy measurement (wheel-speed noise); weighting by the
    effective variance (the linearised errors-in-variables likelihood: Deming regression
    for a straight line) removes most of the attenuation of the stiffness that plain
    least squares on a noisy regressor gives.
    """
    mu = _model(tire, s, d)
    var = s.sig_mu ** 2
    if s.sig_vr > 0.0:
        h = 1e-4
        up = replace(s, vrx=s.vrx + h)
        dn = replace(s, vrx=s.vrx - h)
        slope = (_model(tire, up, d) - _model(tire, dn, d)) / (2 * h)
        var = var + (slope * s.sig_vr) ** 2
    return np.asarray((mu - s.mu) / np.sqrt(var))


def _linear_stiffness(s: _Samples, d: str, nominal: float) -> float:
    """Least-squares slope of |μ| on |slip| in the clearly linear part (|slip| ≤ 2 %)."""
    sel = (np.abs(s.lam) <= 0.02) & (np.abs(s.lam) >= 0.002)
    if np.count_nonzero(sel) < 20:
        return nominal
    lam = s.lam[sel]
    mu = s.mu[sel]
    slope = float(np.sum(lam * mu) / np.sum(lam * lam))
    return abs(slope) if np.isfinite(slope) and slope != 0 else nominal


def fit_lugre_from_log(
    log: pd.DataFrame, vehicle: Vehicle, *, directions: tuple[str, ...] = ("x", "y"),
    min_near_limit: int = 100, max_rel_se: float = 0.10, correlation_time: float = 0.1,
    max_samples: int = 40_000, smooth: int = 5,
) -> tuple[LuGreTire, TireFitReport]:
    """LuGre ``[tire]`` values fitted to one log's measured signals (never its ``ref_`` columns).

    Args:
        log: a drive log; ``ref_`` columns, if present, are dropped before anything is read.
        vehicle: the vehicle file; its ``[tire]`` table is the start point and the value
            kept for every parameter the log does not excite.
        directions: "x" (longitudinal, μ_x against slip ratio) and/or "y".
        min_near_limit: samples needed for C/σ2 (small slip with force) and for the
            friction curve (near the limit) (200 Hz: 100 samples = 0.5 s).
        max_rel_se: largest relative standard error (log-space SE) accepted as "excited".
        correlation_time: s; the residual variance is inflated by correlation_time·rate
            (the force stage's filter correlates consecutive errors).
        max_samples: evenly strided subsample of the pooled corners (cost bound).
        smooth: centred moving-average width (samples) for the wheel speeds.

    Returns:
        (fitted tire, report). The fitted tire is the nominal one with the excited
        quantities replaced (μ_s, μ_c, V_s with θ = 1: this road's friction curve).
    """
    bad = [d for d in directions if d not in ("x", "y")]
    if bad or not directions:
        raise ValueError(f"directions {directions!r}: use 'x', 'y' or both")
    nominal = vehicle.tire
    nom = _nominal_values(nominal)
    data, _ = tire_samples(log, vehicle, smooth=smooth)
    for d in directions:
        s = data[d]
        if len(s.mu) > max_samples:
            idx = np.linspace(0, len(s.mu) - 1, max_samples).astype(int)
            data[d] = s.take(idx)
    t = log["t"].to_numpy(dtype=float)
    rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 200.0
    inflate = max(1.0, correlation_time * rate)

    notes: dict[str, str] = {}
    near = {d: 0 for d in ("x", "y")}
    free_by: dict[str, list[str]] = {"x": [], "y": []}
    for d in ("x", "y"):
        # σ0 z = v_r / (‖v_r‖/(θg) + R|ω|/C): the steady state sees σ0 only through σ0/κ.
        notes[f"sigma0_{d}"] = "steady state depends on σ0/κ only (transient)"
        if d not in directions:
            notes.update({f"C_{d}": "direction not fitted", f"sigma2_{d}": "direction not fitted"})
            continue
        s = data[d]
        # Small-slip samples that carry force: a slip without force (|μ| < 0.05, e.g. the
        # reference filter's own speed error at constant speed) says nothing about C.
        lin = np.count_nonzero((np.abs(s.lam) >= 0.002) & (np.abs(s.lam) <= 0.05)
                               & (np.abs(s.mu) >= 0.05))
        if lin < min_near_limit:
            why = f"{lin} small-slip samples with |μ| ≥ 0.05 < {min_near_limit}"
            notes.update({f"C_{d}": why, f"sigma2_{d}": why})
        else:
            free_by[d] += [f"C_{d}", f"sigma2_{d}"]
    # The friction curve from the longitudinal samples (μ_x against slip ratio); the
    # lateral v̂_y of the reference filter is too uncertain to place a limit.
    if "x" in directions and len(data["x"].mu) >= 50:
        free_by["x"] += list(FRICTION)
    else:
        notes.update({n: "no longitudinal samples" for n in FRICTION})

    def solve(names: list[str], d: str, base: dict[str, float]
              ) -> tuple[dict[str, float], np.ndarray]:
        lo = np.log([BOUNDS[n][0] for n in names])
        hi = np.log([BOUNDS[n][1] for n in names])
        start = np.clip(np.log([base[n] for n in names]), lo + 1e-9, hi - 1e-9)
        if f"C_{d}" in names:  # start at the small-slip slope: the nominal may be 4x off
            i = names.index(f"C_{d}")
            start[i] = np.clip(np.log(_linear_stiffness(data[d], d, base[f"C_{d}"])),
                               lo[i] + 1e-9, hi[i] - 1e-9)
        if "mu_c" in names:
            peak = float(np.quantile(np.abs(data[d].mu), 0.995))
            i = names.index("mu_c")
            start[i] = np.clip(np.log(peak / nominal.mu_s * nominal.mu_c), lo[i] + 1e-9,
                               hi[i] - 1e-9)

        def resid(p: np.ndarray) -> np.ndarray:
            vals = {**base, **dict(zip(names, np.exp(p).tolist(), strict=True))}
            return np.nan_to_num(_weighted_residual(_tire_from(vals, nominal), data[d], d),
                                 nan=1e3)

        sol = least_squares(resid, start, bounds=(lo, hi), method="trf", x_scale=1.0,
                            max_nfev=300)
        vals = {**base, **dict(zip(names, np.exp(sol.x).tolist(), strict=True))}
        s2 = float(sol.fun @ sol.fun) / max(sol.fun.size - len(names), 1) * inflate
        # Marginal SE from the SVD of J: a direction the data do not see (tiny singular
        # value) gives every parameter loading on it a huge SE instead of none.
        _, sv, vt = np.linalg.svd(sol.jac, full_matrices=False)
        sv = np.maximum(sv, 1e-300)
        se = np.sqrt(s2 * np.sum((vt / sv[:, None]) ** 2, axis=0))
        on_bound = (sol.x <= lo + 1e-3) | (sol.x >= hi - 1e-3)
        return vals, np.where(on_bound, np.inf, se)

    def prune(free: list[str], d: str, base: dict[str, float]
              ) -> tuple[dict[str, float], dict[str, float]]:
        """Fit the free set, drop what the data do not determine (largest SE first), refit."""
        vals, se_map = dict(base), {}
        while free:
            vals, se = solve(free, d, base)
            se_map = dict(zip(free, se.tolist(), strict=True))
            weak = [n for n in free if not se_map[n] <= max_rel_se]
            if not weak:
                break
            worst = max(weak, key=lambda n: se_map[n])
            notes[worst] = ("on a bound" if not np.isfinite(se_map[worst])
                            else f"rel. SE {100 * se_map[worst]:.0f} % > {100 * max_rel_se:.0f} %")
            free.remove(worst)
            if worst == "mu_c":  # no friction level, no Stribeck shape either
                for n in ("ratio_s", "v_s"):
                    if n in free:
                        free.remove(n)
                        notes[n] = "mu_c not excited"
        if not free:
            vals, se_map = dict(base), {}
        return vals, se_map

    vals, se_map = dict(nom), {}
    for d in ("x", "y"):
        free = free_by[d]
        if not free:
            continue
        v_d, se_d = prune(free, d, vals)
        if "mu_c" in free:
            # Near-limit samples: |μ_x| at least half the fitted friction level g(‖v_r‖)
            # (on the LuGre steady-state curve μ = g·Cλ/(g + Cλ), where it has bent to half
            # the linear line). Without enough of them the "friction" is an extrapolation.
            fitted = _tire_from(v_d, nominal)
            sd = data[d]
            vn = np.hypot(sd.vrx, sd.vry)
            g = fitted.mu_c + (fitted.mu_s - fitted.mu_c) * np.exp(
                -((vn / fitted.v_s) ** fitted.alpha))
            near[d] = int(np.count_nonzero((np.abs(sd.mu) >= 0.5 * g)
                                           & (np.sign(sd.mu) == np.sign(sd.lam))))
            if near[d] < min_near_limit:
                for n in FRICTION:
                    if n in free:
                        free.remove(n)
                        notes[n] = (f"{near[d]} near-limit samples < {min_near_limit} "
                                    f"(|μ_x| ≥ half the fitted level {fitted.mu_c:.2f})")
                v_d, se_d = prune(free, d, vals)
        vals = {**vals, **{n: v_d[n] for n in free}}
        se_map.update({n: se_d[n] for n in free})
    free = [n for n in nom if n in se_map]
    used = [d for d in directions if len(data[d].mu) >= 50]
    final = {n: (vals[n] if n in free else nom[n]) for n in nom}
    tire = _tire_from(final, nominal)

    params = tuple(ParamFit(n, nom[n], final[n], n in free, float(se_map.get(n, np.inf)),
                            "" if n in free else notes.get(n, "not fitted"))
                   for n in nom)
    # The nominal tire's friction curve with θ chosen to match this road's level, so the
    # nominal residual measures the shape (stiffness), not the road.
    rms_nom, rms_fit = {}, {}
    for d in used:
        s = data[d]
        peak = max(float(np.quantile(np.abs(s.mu), 0.995)), 0.05)
        theta = peak / nominal.mu_s
        mx, my = lugre_steady_state(s.vrx, s.vry, s.omega_r, theta, nominal)
        rms_nom[d] = float(np.sqrt(np.nanmean(((mx if d == "x" else my) - s.mu) ** 2)))
        # Same θ for the fitted tire where its friction level is the nominal one.
        th_fit = 1.0 if "mu_c" in free else theta
        fx, fy = lugre_steady_state(s.vrx, s.vry, s.omega_r, th_fit, tire)
        rms_fit[d] = float(np.sqrt(np.nanmean(((fx if d == "x" else fy) - s.mu) ** 2)))
    sx = data["x"].lam
    report = TireFitReport(
        params=params,
        samples={d: len(data[d].mu) for d in ("x", "y")},
        near_limit=near,
        slip_range=(float(sx.min()), float(sx.max())) if sx.size else (0.0, 0.0),
        rms_nominal=rms_nom, rms_fit=rms_fit,
        peak_mu=lugre_peak_mu(1.0, tire, float(np.median(data["x"].omega_r))
                              if data["x"].omega_r.size else 20.0))
    return tire, report
