"""Body and tire parameters of ``vestim calibrate``, identified from ordinary drive logs.

Only measured channels are read: every ``ref_`` (ground-truth) column is dropped first.
All signals are low-passed with a zero-phase 2nd-order Butterworth filter (``FC`` Hz) before
any derivative or regression, so the linear relations below hold for the filtered signals
too; each regression carries an intercept per log (sensor biases).

Body (:func:`identify_body`) — from the rates and the IMU's gravity components:

* roll gradient c_φ = φ/a_y (rad per m/s²). A body-fixed accelerometer reads
  a_y,m = a_y + g sin φ, so the true lateral acceleration's rate is ȧ_y = ȧ_y,m − g p
  (p: roll rate ≈ φ̇). With φ = c_φ a_y (quasi-static roll), p = c_φ ȧ_y: a regression of
  the roll rate on ȧ_y,m − g p. It needs no speed, no sideslip (v̇_y never enters) and no
  integration of the gyro (its bias is the intercept). The body's roll mode (~1.5–2 Hz)
  against the 1 Hz low-pass biases the gain by a few per cent at most.
* pitch gradient c_θ = −θ/a_x (θ > 0 nose down, so c_θ > 0 for a car that squats when
  accelerating), the same from the pitch rate q and a_x,m = a_x − g sin θ: θ̇ = −c_θ ȧ_x,
  ȧ_x = ȧ_x,m + g θ̇, θ̇ = q − r φ (the roll-coupled yaw rate removed with φ = c_φ a_y).

Tires (:func:`identify_tires`):

* axle cornering stiffness C_f, C_r (N/rad, axle total, linear range). Single-track model
  with the axle forces from the body's equations, F_yf = (m a_y l_r + I_z ṙ)/L,
  F_yr = (m a_y l_f − I_z ṙ)/L (a_y = a_y,m/(1 + g c_φ): the roll's gravity component
  removed), and the slip-angle difference, in which the unknown lateral velocity cancels:
  α_f − α_r = δ − L r/v, with α = F_y/C per axle:

      δ − L r/v = F_yf/C_f − F_yr/C_r + b.

  Steady cornering fixes only the understeer gradient (F_yf/F_yr = l_r/l_f); the yaw
  acceleration of transients separates the axles. Both sides are high-passed at
  ``HP_CORNER`` (what drifts with a_y and is not in the linear model: camber thrust, the
  curvature of a ramp). Used: |a_y| ≤ ``AY_LINEAR`` (halved while the data show curvature,
  :func:`_linear_cornering`), |a_x| ≤ ``AX_PURE`` (no combined slip), v ≥ ``V_MIN``, logs
  whose |a_y| reaches ``NEED_AY``, at least ``CORNER_MIN_S`` of samples.
* longitudinal slip stiffness per axle C_x (N per unit slip ratio) of a driven axle whose
  other axle rolls freely (2WD, driving, not braking): slip κ = (R ω − v)/v against the
  free-rolling axle's R ω, axle force F_x = Σ(T − I_w ω̇)/R from the torque channels (or
  m a_x when the log has none), regression F_x = C_x κ + b over |κ| ≤ ``SLIP_LINEAR``.
* a road change inside a log (wet, soft ground) is found by a change-point test
  (:func:`_change_cut`) and the log is used up to it: the car's value is the one it starts
  with.
* the lumped LuGre ``[tire]`` values of 000/001 through
  :func:`vestim.design.tire_fit.fit_lugre_from_log`, one fit per log, combined.

Every value is an :class:`~vestim.io.calibration.Identified`: one-σ from the
regression (residual variance inflated by the residual's integrated autocorrelation time,
the filtered samples being far from independent; for the tire fits at least the block
jackknife's spread, which sees model error), or "not excited" with the base value (the
vehicle file's ``[suspension]``/``[stiffness]``/``[tire]``, or the generic stiffness prior)
when the logs do not determine it (relative σ above ``MAX_REL_SIGMA``, too little range).

Known limits (measured, see tests/design/test_calibrate_body_tire.py): on a low-μ or wet
log that nears saturation the secant is read as stiffness when the smaller |a_y| ranges
carry too little data to show the curvature (crossplant x08 snow: 0.68 of the small-slip
value; vestim.sim lc_wet: 0.72); C_x from the free-axle slip reads 0.82–1.10 of the
tangent.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import butter, sosfiltfilt

from vestim.constants import CORNERS, G
from vestim.design.tire_fit import fit_lugre_from_log
from vestim.errors import LogFormatError
from vestim.estimators.stiffness.config import StiffnessPrior
from vestim.estimators.stiffness.model import pitch_gradient, roll_gradient
from vestim.io.calibration import Identified
from vestim.io.vehicle import Vehicle

FC = 1.0
"""Hz, zero-phase low-pass of every signal before differentiation and regression."""

MAX_REL_SIGMA = 0.10
"""Largest relative one-σ accepted as "excited"."""

AY_LINEAR = 3.0
"""m/s², widest |a_y| range used for the cornering stiffness (0.3 g); halved while the
data show curvature (:func:`_linear_cornering`)."""

CORNER_MIN_S = 4.0
"""s of usable cornering samples below which the cornering stiffness is "not excited" (one
step steer's transient is too little: tire lag and roll dynamics dominate it)."""

AY_LINEAR_MIN = 0.7
"""m/s², smallest |a_y| range the linearity test (:func:`_linear_cornering`) goes down to."""

AX_PURE = 1.0
"""m/s², largest |a_x| used for the cornering stiffness (no combined slip)."""

V_MIN = 5.0
"""m/s, lowest speed used for slip quantities (1/v amplifies the wheel-speed noise)."""

DELTA_STRAIGHT = 0.02
"""rad, largest |road-wheel angle| for the longitudinal slip stiffness (δ²/2 = 2e-4 of
geometric wheel-speed difference between the axles, well below the slips used)."""

SLIP_LINEAR = 0.03
"""Largest |slip ratio| used for the longitudinal slip stiffness (linear range)."""

NEED_AY = 1.0
"""m/s², |a_y| a log must reach to take part in the roll-gradient fit."""

NEED_AX = 0.5
"""m/s², |a_x| a log must reach to take part in the pitch-gradient fit."""

JACK_S = 5.0
"""s, block length of the jackknife that bounds the one-σ from below (model error); an
eighth of the data when that is shorter (at least 1 s)."""

MIN_SAMPLES = 200
"""Fewest usable samples (1 s at 200 Hz) for a regression on one log."""


# ---------------------------------------------------------------- helpers
def _measured(log: pd.DataFrame) -> pd.DataFrame:
    """The log without any ground-truth (``ref_``) or private (``_``) column."""
    return log[[c for c in log.columns if not str(c).startswith(("ref_", "_"))]]


def _name(log: pd.DataFrame, i: int) -> str:
    for key in ("name", "log", "file", "maneuver"):
        v = log.attrs.get(key)
        if isinstance(v, str) and v:
            return v
    return f"log {i + 1}"


@dataclass
class _Log:
    """One log's low-passed signals (SI units, ISO axes)."""

    name: str
    t: np.ndarray
    fs: float
    cols: pd.DataFrame

    def has(self, *names: str) -> bool:
        return all(n in self.cols.columns and np.isfinite(self.cols[n].to_numpy(float)).all()
                   for n in names)

    def lp(self, name: str) -> np.ndarray:
        return _lowpass(self.cols[name].to_numpy(dtype=float), self.fs)

    def diff(self, x: np.ndarray) -> np.ndarray:
        return np.gradient(x, self.t)


def _lowpass(x: np.ndarray, fs: float, fc: float = FC) -> np.ndarray:
    sos = butter(2, min(fc / (0.5 * fs), 0.99), output="sos")
    return np.asarray(sosfiltfilt(sos, x))


HP_CORNER = 0.2
"""Hz, zero-phase high-pass of both sides of the cornering regression: it keeps the yaw
transients that separate the axles and removes what drifts slowly with the lateral
acceleration and is not in the linear single-track model (camber thrust and the curvature
of the tire through a ramp, roll steer), as the pipeline's online regression does
(:class:`vestim.estimators.velocity.reference.StiffnessParams`, τ_hp = 1 s). Chosen on the
crossplant hold-out: 0.15–0.25 Hz give the same values within 2 % except where one short
transient is all there is (x08 from x07: front 0.86–1.01; now below ``CORNER_MIN_S``);
none (0 Hz) leaves the front 1–3 % lower."""


def _highpass(x: np.ndarray, fs: float, fc: float) -> np.ndarray:
    sos = butter(2, fc / (0.5 * fs), btype="high", output="sos")
    return np.asarray(sosfiltfilt(sos, x - x.mean()))


def _prepare(logs: Sequence[pd.DataFrame]) -> list[_Log]:
    out = []
    for i, log in enumerate(logs):
        m = _measured(log)
        name = _name(log, i)
        if "t" not in m.columns:
            raise LogFormatError(f"{name}: no column 't' (time in s); every drive log needs one")
        t = m["t"].to_numpy(dtype=float)
        dt = np.diff(t)
        bad = np.nonzero(~(dt > 0))[0]
        if bad.size:
            raise LogFormatError(f"{name}: column 't' does not increase at row {int(bad[0]) + 1} "
                                 f"({t[bad[0]]} then {t[bad[0] + 1]}); sort the log by time")
        if len(m) < 3 * MIN_SAMPLES // 2:
            continue  # too short to say anything: contributes nothing
        out.append(_Log(name, t, float(1.0 / np.median(dt)), m))
    return out


def _tau_samples(e: np.ndarray) -> float:
    """Integrated autocorrelation time of ``e`` in samples (≥ 1): the ACF summed up to its
    first zero crossing. Low-passed residuals are correlated over ~fs/(2 FC) samples."""
    e = e - e.mean()
    n = e.size
    if n < 8 or not np.any(e):
        return 1.0
    f = np.fft.rfft(e, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    acf = acf / acf[0]
    neg = np.nonzero(acf <= 0)[0]
    stop = int(neg[0]) if neg.size else n
    return max(1.0, 1.0 + 2.0 * float(acf[1:stop].sum()))


@dataclass
class _Fit:
    """Pooled least squares y = X β + (one intercept per log)."""

    beta: np.ndarray
    cov: np.ndarray
    n: int
    seconds: float
    names: list[str]


def _pooled(parts: list[tuple[str, np.ndarray, np.ndarray, float]], jackknife: bool = False
            ) -> _Fit | None:
    """Least squares over several logs, each with its own intercept (the regressors and the
    regressand are centred per log). ``parts``: (name, X (n, k), y (n,), fs). ``jackknife``:
    the covariance is at least the block jackknife's (for fits whose residual is model error
    rather than sensor noise)."""
    parts = [p for p in parts if p[2].size >= MIN_SAMPLES]
    if not parts:
        return None
    xs = [p[1] - p[1].mean(axis=0) for p in parts]
    ys = [p[2] - p[2].mean() for p in parts]
    x = np.vstack(xs)
    y = np.concatenate(ys)
    k = x.shape[1]
    xtx = x.T @ x
    if np.linalg.cond(xtx) > 1e12:
        return None
    beta = np.linalg.solve(xtx, x.T @ y)
    e = y - x @ beta
    dof = max(y.size - k - len(parts), 1)
    s2 = float(e @ e) / dof
    # correlated residuals: inflate by the integrated autocorrelation time, per log
    pos = np.cumsum([0] + [len(v) for v in ys])
    tau = max(_tau_samples(e[a:b]) for a, b in itertools.pairwise(pos))
    cov = np.linalg.inv(xtx) * s2 * tau
    secs_total = float(sum(p[2].size / p[3] for p in parts))
    # Model error is not white noise: a delete-one-block jackknife (blocks of JACK_S) sees
    # how much the answer moves with the data used; the larger of the two covariances.
    block_s = max(min(JACK_S, secs_total / 8.0), 1.0)
    blocks = [(a + i, min(a + i + int(block_s * fs), b))
              for (a, b), fs in zip(itertools.pairwise(pos), [p[3] for p in parts],
                                    strict=True)
              for i in range(0, b - a, int(block_s * fs))]
    if jackknife and len(blocks) >= 4:
        reps = []
        for a, b in blocks:
            xtx_j = xtx - x[a:b].T @ x[a:b]
            if np.linalg.cond(xtx_j) > 1e12:
                continue
            reps.append(np.linalg.solve(xtx_j, x.T @ y - x[a:b].T @ y[a:b]))
        if len(reps) >= 4:
            r = np.asarray(reps)
            d = r - r.mean(axis=0)
            jack = (len(r) - 1) / len(r) * (d.T @ d)
            if np.all(np.diag(jack) > np.diag(cov)):
                cov = jack
    secs = float(sum(p[2].size / p[3] for p in parts))
    return _Fit(beta, cov, int(y.size), secs, [p[0] for p in parts])


CHANGE_MIN = 0.10
"""Smallest relative change of every coefficient that counts as a tire change in a log."""

CHANGE_F = 6.0
"""F statistic (effective samples) a change point needs: a road change within a log."""


def _change_cut(name: str, t: np.ndarray, x: np.ndarray, y: np.ndarray
                ) -> tuple[int, str | None]:
    """Where the log's tire changes (a road change within the log, e.g. wet or soft ground),
    as the number of leading samples to keep, and a note; (len, None) when it does not.

    Change-point scan: for each split time τ (1 s steps, 20–80 % of the used time) the
    regression y = x β + x·H(t − τ) Δ + intercepts is compared with the one without Δ by an
    F test on effective samples (residual autocorrelation). A change is declared at the best
    τ when F ≥ ``CHANGE_F`` and every coefficient moves by ≥ ``CHANGE_MIN`` in the same
    direction (a road scales all axles alike). The car's value is the one the log starts
    with, so the samples before τ are kept."""
    n, k = x.shape
    if n < 4 * MIN_SAMPLES or t[-1] - t[0] < 10.0:
        return n, None
    xc = x - x.mean(axis=0)
    yc = y - y.mean()
    beta0, *_ = np.linalg.lstsq(xc, yc, rcond=None)
    e0 = yc - xc @ beta0
    rss0 = float(e0 @ e0)
    tau = _tau_samples(e0)
    best: tuple[float, float, np.ndarray] | None = None
    for cut_t in np.arange(t[0] + 0.2 * (t[-1] - t[0]), t[0] + 0.8 * (t[-1] - t[0]), 1.0):
        h = (t > cut_t).astype(float)
        z = np.hstack([x, x * h[:, None], h[:, None]])
        z = z - z.mean(axis=0)
        sol, *_ = np.linalg.lstsq(z, yc, rcond=None)
        e1 = yc - z @ sol
        rss1 = float(e1 @ e1)
        if best is None or rss1 < best[0]:
            best = (rss1, float(cut_t), sol)
    if best is None:
        return n, None
    rss1, cut_t, sol = best
    n_eff = n / tau
    f_stat = ((rss0 - rss1) / (k + 1)) / max(rss1 / max(n_eff - 2 * k - 2, 1.0), 1e-300)
    rel = sol[k:2 * k] / sol[:k]
    if f_stat < CHANGE_F or not (np.all(rel >= CHANGE_MIN) or np.all(rel <= -CHANGE_MIN)):
        return n, None
    keep = int(np.searchsorted(t, cut_t))
    return keep, (f"{name} cut at t = {cut_t:.0f} s (its tire changed: coefficients "
                  f"{', '.join(f'{100 * r:+.0f} %' for r in rel)}, F = {f_stat:.0f})")


def _span(lo: float, hi: float, unit: str) -> str:
    return f"{lo:+.3g}…{hi:+.3g} {unit}"


# ---------------------------------------------------------------- body
def _gradient_fit(logs: list[_Log], rate: str, accel: str, sign: float,
                  c_roll: float | None, need: float) -> tuple[_Fit | None, tuple[float, float]]:
    """Regress the body rate on the rate of the true acceleration (see the module text).

    Only logs whose |acceleration| reaches ``need`` take part: a log without excitation adds
    only regressor noise, which attenuates the pooled slope (errors in variables)."""
    parts = []
    lo, hi = math.inf, -math.inf
    for lg in logs:
        if not lg.has(rate, accel):
            continue
        w = lg.lp(rate)
        a_m = lg.lp(accel)
        lo = min(lo, float(np.quantile(a_m, 0.005)))
        hi = max(hi, float(np.quantile(a_m, 0.995)))
        if float(np.quantile(np.abs(a_m), 0.995)) < need:
            continue
        if c_roll is not None and lg.has("yaw_rate", "ay"):
            w = w - lg.lp("yaw_rate") * c_roll * lg.lp("ay")
        # roll: ȧ_y = ȧ_y,m − g p ; pitch: ȧ_x = ȧ_x,m + g θ̇
        a_dot = lg.diff(a_m) - sign * G * w
        parts.append((lg.name, a_dot[:, None], w, lg.fs))
    return _pooled(parts), (lo, hi)


def _excitation(fit: _Fit, span: tuple[float, float], need: float, value: float,
                sigma: float, what: str) -> str | None:
    """Why a gradient fit is not excited, or None."""
    if max(abs(span[0]), abs(span[1])) < need:
        return f"{what} within {_span(*span, 'm/s^2')}, below the ±{need:g} m/s^2 needed"
    if not (value > 0 and sigma / value <= MAX_REL_SIGMA):
        return (f"{what} fit {value:.3g} ± {sigma:.2g} rad per m/s^2 is not determined "
                f"(relative σ above {MAX_REL_SIGMA:.0%} or wrong sign)")
    return None


def identify_body(logs: Sequence[pd.DataFrame], vehicle: Vehicle) -> dict[str, Identified]:
    """Roll and pitch gradient of the sprung body from the logs' rates and accelerations.

    Args:
        logs: drive logs (spec format; ``ref_`` columns are dropped unread).
        vehicle: the vehicle file; its ``[suspension]`` gives the base values kept when the
            logs do not excite a gradient (:func:`vestim.estimators.stiffness.model.roll_gradient`).

    Returns:
        ``roll_gradient`` (rad per m/s² of lateral acceleration, φ = c_φ a_y, > 0 for a
        body that rolls outward) and ``pitch_gradient`` (rad per m/s² of longitudinal
        acceleration, c_θ = −θ/a_x, θ > 0 nose down).
    """
    lg = _prepare(logs)
    out: dict[str, Identified] = {}
    fit, span = _gradient_fit(lg, "roll_rate", "ay", +1.0, None, NEED_AY)
    base = roll_gradient(vehicle)
    unit = "rad/(m/s^2)"
    c_roll: float | None = None
    if fit is None:
        out["roll_gradient"] = Identified.not_excited(
            base, f"no log with roll_rate and |ay| reaching {NEED_AY:g} m/s^2 "
            f"(a_y {_span(*span, 'm/s^2')})", unit)
    else:
        v, s = float(fit.beta[0]), float(math.sqrt(fit.cov[0, 0]))
        why = _excitation(fit, span, NEED_AY, v, s, "lateral acceleration")
        if why is None:
            c_roll = v
            out["roll_gradient"] = Identified(
                v, s, True, f"{', '.join(fit.names)}: {fit.seconds:.0f} s, roll rate against "
                f"the lateral-acceleration rate, a_y {_span(*span, 'm/s^2')}", unit)
        else:
            out["roll_gradient"] = Identified.not_excited(base, why, unit)
    fit, span = _gradient_fit(lg, "pitch_rate", "ax", -1.0,
                              c_roll if c_roll is not None else base, NEED_AX)
    base = pitch_gradient(vehicle)
    if fit is None:
        out["pitch_gradient"] = Identified.not_excited(
            base, f"no log with pitch_rate and |ax| reaching {NEED_AX:g} m/s^2 "
            f"(a_x {_span(*span, 'm/s^2')})", unit)
    else:
        # θ̇ = −c_θ ȧ_x
        v, s = -float(fit.beta[0]), float(math.sqrt(fit.cov[0, 0]))
        why = _excitation(fit, span, NEED_AX, v, s, "longitudinal acceleration")
        if why is None:
            out["pitch_gradient"] = Identified(
                v, s, True, f"{', '.join(fit.names)}: {fit.seconds:.0f} s, pitch rate against "
                f"the longitudinal-acceleration rate, a_x {_span(*span, 'm/s^2')}", unit)
        else:
            out["pitch_gradient"] = Identified.not_excited(base, why, unit)
    return out


# ---------------------------------------------------------------- tires
def _wheel_speeds(lg: _Log, radius: float) -> np.ndarray | None:
    names = [f"omega_{c}" for c in CORNERS]
    if not lg.has(*names):
        return None
    return np.stack([lg.lp(n) for n in names], axis=1) * radius


def _free_axle(drivetrain: str) -> int | None:
    """Index of the undriven axle (0 front, 1 rear), None for AWD."""
    return {"fwd": 1, "rwd": 0}.get(drivetrain)


def _road_wheel_angle(lg: _Log, vehicle: Vehicle) -> np.ndarray | None:
    if lg.has("delta_fl", "delta_fr"):
        return 0.5 * (lg.lp("delta_fl") + lg.lp("delta_fr"))
    if lg.has("steering_wheel_angle"):
        return lg.lp("steering_wheel_angle") / vehicle.body.steering_ratio
    return None


ROLL_CROSSOVER = 0.1
"""Hz, crossover of the roll-angle estimate: the integrated roll rate above it, the
quasi-static roll c_φ a_y below it (the gyro bias never integrates up)."""


def _lateral_acceleration(lg: _Log, c_roll: float) -> np.ndarray:
    """True lateral acceleration a_y = cos φ·a_y,m − sin φ·a_z,m (m/s²; the body-fixed IMU's
    specific force rotated back by the roll angle φ). φ: complementary estimate, the roll
    rate integrated (high-passed at ``ROLL_CROSSOVER``) plus c_φ a_y,m/(1 + g c_φ) below it —
    the roll lags a_y by the body's roll mode, which the quasi-static c_φ a_y alone misses."""
    ay_m = lg.lp("ay")
    phi_qs = c_roll * ay_m / (1.0 + G * c_roll)
    if not lg.has("roll_rate"):
        return ay_m / (1.0 + G * c_roll)
    p = lg.lp("roll_rate")
    dt = np.diff(lg.t, prepend=lg.t[0])
    phi_int = np.cumsum(p * dt)
    phi = (_lowpass(phi_qs, lg.fs, ROLL_CROSSOVER)
           + phi_int - _lowpass(phi_int, lg.fs, ROLL_CROSSOVER))
    az = lg.lp("az") if lg.has("az") else np.full_like(ay_m, G)
    return np.cos(phi) * ay_m - np.sin(phi) * az


def _cornering(logs: list[_Log], vehicle: Vehicle, c_roll: float, ay_limit: float
               ) -> tuple[_Fit | None, str]:
    """The single-track slip-difference regression (module text); returns the fit of
    (1/C_f, 1/C_r) and a description of the data used."""
    b = vehicle.body
    wb = b.lf + b.lr
    free = _free_axle(b.drivetrain)
    parts = []
    cuts: list[str] = []
    ay_hi = 0.0
    for lg in logs:
        ws = _wheel_speeds(lg, b.wheel_radius)
        delta = _road_wheel_angle(lg, vehicle)
        if ws is None or delta is None or not lg.has("ay", "yaw_rate", "ax"):
            continue
        v = ws.mean(axis=1) if free is None else ws[:, 2 * free:2 * free + 2].mean(axis=1)
        r = lg.lp("yaw_rate")
        r_dot = lg.diff(r)
        ay = _lateral_acceleration(lg, c_roll)
        ax = lg.lp("ax")
        use = (v >= V_MIN) & (np.abs(ay) <= ay_limit) & (np.abs(ax) <= AX_PURE)
        if (np.count_nonzero(use) < MIN_SAMPLES
                or float(np.quantile(np.abs(ay), 0.995)) < NEED_AY):
            continue  # a log without cornering adds only regressor noise
        fyf = (b.mass * ay * b.lr + b.yaw_inertia * r_dot) / wb
        fyr = (b.mass * ay * b.lf - b.yaw_inertia * r_dot) / wb
        y = delta - wb * r / np.maximum(v, V_MIN)
        x = np.stack([fyf, -fyr], axis=1)
        if HP_CORNER > 0:
            y = _highpass(y, lg.fs, HP_CORNER)
            x = np.stack([_highpass(c, lg.fs, HP_CORNER) for c in x.T], axis=1)
        keep, note = _change_cut(lg.name, lg.t[use], x[use], y[use])
        if note:
            cuts.append(note)
        parts.append((lg.name, x[use][:keep], y[use][:keep], lg.fs))
        ay_hi = max(ay_hi, float(np.quantile(np.abs(ay[use]), 0.995)))
    fit = _pooled(parts, jackknife=True)
    if fit is not None and fit.seconds < CORNER_MIN_S:
        return None, (f"{', '.join(fit.names)}: only {fit.seconds:.1f} s of cornering in the "
                      f"linear range (|a_y| ≤ {ay_limit:g} m/s^2), {CORNER_MIN_S:g} s needed")
    if fit is None:
        return None, (f"no cornering: no log with |a_y| reaching {NEED_AY:g} m/s^2 and "
                      f"{MIN_SAMPLES} samples of wheel speeds, steering, ay, ax and yaw rate "
                      f"at v ≥ {V_MIN:g} m/s, |a_y| ≤ {ay_limit:g} m/s^2, |a_x| ≤ {AX_PURE:g} m/s^2")
    return fit, (f"{', '.join(fit.names)}: {fit.seconds:.0f} s at v ≥ {V_MIN:g} m/s, "
                 f"|a_y| ≤ {ay_hi:.2g} m/s^2 (linear range ≤ {ay_limit:g}), |a_x| ≤ {AX_PURE:g}"
                 + "".join(f"; {c}" for c in cuts))


def _longitudinal(logs: list[_Log], vehicle: Vehicle, axle: int
                  ) -> tuple[_Fit | None, str]:
    """Slip stiffness of ``axle`` (0 front, 1 rear) against the free-rolling other axle."""
    b = vehicle.body
    free = _free_axle(b.drivetrain)
    if free is None or free == axle:
        return None, ("no free-rolling axle to measure its slip against"
                      if free is None else "axle is not driven (its brake slip has no "
                      "free-rolling reference)")
    parts = []
    cuts: list[str] = []
    k_lo, k_hi, f_hi = math.inf, -math.inf, 0.0
    tq = [f"torque_{c}" for c in CORNERS[2 * axle:2 * axle + 2]]
    tq_free = [f"torque_{c}" for c in CORNERS[2 * free:2 * free + 2]]
    for lg in logs:
        ws = _wheel_speeds(lg, b.wheel_radius)
        if ws is None or not lg.has("ax"):
            continue
        v = ws[:, 2 * free:2 * free + 2].mean(axis=1)
        wa = ws[:, 2 * axle:2 * axle + 2]
        kappa = (wa.mean(axis=1) - v) / np.maximum(v, V_MIN)
        if lg.has(*tq):
            torque = lg.lp(tq[0]) + lg.lp(tq[1])
            omega_dot = lg.diff(wa.sum(axis=1)) / b.wheel_radius
            fx = (torque - b.wheel_inertia * omega_dot) / b.wheel_radius
            driving = torque > 0.0
            if lg.has(*tq_free):  # free rolling: no brake torque on the reference axle
                driving &= np.abs(lg.lp(tq_free[0]) + lg.lp(tq_free[1])) < 0.02 * np.abs(torque) + 40.0
        else:
            fx = b.mass * lg.lp("ax")
            driving = fx > 0.0
        # near-straight running only: in a turn the axles run on different radii, which
        # shifts the steered axle's wheel speed against the free one by ~δ²/2
        delta = _road_wheel_angle(lg, vehicle)
        straight = (np.abs(delta) <= DELTA_STRAIGHT if delta is not None
                    else np.ones_like(v, dtype=bool))
        use = driving & straight & (v >= V_MIN) & (np.abs(kappa) <= SLIP_LINEAR)
        if np.count_nonzero(use) < MIN_SAMPLES:
            continue
        keep, note = _change_cut(lg.name, lg.t[use], kappa[use, None], fx[use])
        if note:
            cuts.append(note)
        parts.append((lg.name, kappa[use, None][:keep], fx[use][:keep], lg.fs))
        k_lo, k_hi = min(k_lo, float(kappa[use].min())), max(k_hi, float(kappa[use].max()))
        f_hi = max(f_hi, float(fx[use].max()))
    fit = _pooled(parts, jackknife=True)
    if fit is None:
        return None, (f"no {MIN_SAMPLES} samples of driving above {V_MIN:g} m/s with "
                      f"|slip ratio| ≤ {SLIP_LINEAR:g}")
    return fit, (f"{', '.join(fit.names)}: {fit.seconds:.0f} s of driving, slip ratio "
                 f"{_span(k_lo, k_hi, '')}, F_x up to {f_hi:.0f} N" + "".join(f"; {c}" for c in cuts))


def _stiffness_value(fit: _Fit | None, i: int, inverse: bool, base: float, why: str,
                     unit: str, need_excitation: str) -> Identified:
    if fit is None:
        return Identified.not_excited(base, why, unit)
    b, s = float(fit.beta[i]), float(math.sqrt(fit.cov[i, i]))
    value, sigma = (1.0 / b, s / b**2) if inverse and b != 0 else (b, s)
    if not (value > 0 and sigma / value <= MAX_REL_SIGMA):
        return Identified.not_excited(
            base, f"{need_excitation}: fit {value:.4g} ± {sigma:.2g} {unit} from {why} "
            f"is not determined (relative σ above {MAX_REL_SIGMA:.0%} or wrong sign)", unit)
    return Identified(value, sigma, True, why, unit)


def _linear_cornering(lg: list[_Log], vehicle: Vehicle, c_roll: float,
                      prior: tuple[float, float, float, float], need: str
                      ) -> dict[str, Identified]:
    """Cornering stiffness from the widest |a_y| range that is still linear: starting at
    ``AY_LINEAR``, the range is halved while the fit on half the range differs from it by
    more than 2 combined σ plus 5 % on either axle (the secant of a saturating tire falls
    with the range; μ is not known, so the data must show where the linear part ends)."""
    def fit_at(limit: float) -> dict[str, Identified]:
        fit, why = _cornering(lg, vehicle, c_roll, limit)
        return {"cy_f": _stiffness_value(fit, 0, True, prior[2], why, "N/rad", need),
                "cy_r": _stiffness_value(fit, 1, True, prior[3], why, "N/rad", need)}

    limit = AY_LINEAR
    cur = fit_at(limit)
    while limit / 2 >= AY_LINEAR_MIN:
        half = fit_at(limit / 2)
        if not all(half[k].excited for k in half):
            break  # the smaller range does not determine it: linearity cannot be tested
        if not all(cur[k].excited for k in cur):
            cur, limit = half, limit / 2
            continue
        bent = any(abs(cur[k].value - half[k].value)
                   > 2 * math.hypot(cur[k].sigma, half[k].sigma) + 0.05 * half[k].value
                   for k in cur)
        if not bent:
            break
        cur, limit = half, limit / 2
    return cur


_LUGRE = ("sigma0_x", "sigma1_x", "sigma2_x", "kappa_x", "sigma0_y", "sigma1_y", "sigma2_y",
          "kappa_y", "mu_s", "mu_c", "v_s", "alpha")
_LUGRE_UNITS = {"sigma0": "1/m", "sigma1": "s/m", "sigma2": "s/m", "kappa": "1/m",
                "mu_s": "-", "mu_c": "-", "v_s": "m/s", "alpha": "-"}


FRICTION_FITS = ("mu_c", "ratio_s", "v_s")
"""fit_lugre_from_log's friction-curve quantities: a road's, not the car's."""


def _combine(values: list[tuple[str, float, float]]) -> tuple[float, float, float]:
    """Inverse-variance mean in log space of (name, value, rel_se); returns (value, rel σ,
    Birge ratio √(χ²/dof) — > 2: the logs disagree)."""
    lv = np.log([v for _, v, _ in values])
    w = 1.0 / np.square([max(s, 1e-6) for _, _, s in values])
    m = float(np.sum(w * lv) / np.sum(w))
    rel = float(1.0 / math.sqrt(np.sum(w)))
    birge = float(math.sqrt(np.sum(w * (lv - m) ** 2) / (len(lv) - 1))) if len(lv) > 1 else 1.0
    return math.exp(m), rel * max(1.0, birge), birge


def _lugre(raw: Sequence[pd.DataFrame], vehicle: Vehicle) -> dict[str, Identified]:
    """LuGre values from :func:`fit_lugre_from_log` per log, combined over the logs."""
    nominal = vehicle.tire
    per: dict[str, list[tuple[str, float, float]]] = {}
    notes: dict[str, str] = {}
    for i, log in enumerate(raw):
        name = _name(log, i)
        _, rep = fit_lugre_from_log(_measured(log), vehicle)
        for p in rep.params:
            if p.excited:
                per.setdefault(p.name, []).append((name, p.value, p.rel_se))
            else:
                notes.setdefault(p.name, f"{name}: {p.note}")
    out: dict[str, Identified] = {}

    def unit(key: str) -> str:
        return _LUGRE_UNITS.get(key, _LUGRE_UNITS.get(key[:-2], "-"))

    def from_fits(key: str, fitted: str, transform: float | None = None) -> None:
        base = float(getattr(nominal, key))
        fits = per.get(fitted, [])
        if not fits:
            out[key] = Identified.not_excited(base, notes.get(fitted, "not fitted"), unit(key))
            return
        v, rel, birge = _combine(fits)
        if birge > 3.0:
            out[key] = Identified.not_excited(
                base, f"the logs disagree ({', '.join(f'{n} {x:.3g}' for n, x, _ in fits)}; "
                f"Birge ratio {birge:.1f} > 3): the road or tire differs between them",
                unit(key))
            return
        if transform is not None:  # κ = σ0,nominal / C
            v = transform / v
        road = " — the friction of these logs' roads" if fitted in FRICTION_FITS else ""
        out[key] = Identified(v, v * rel, True, f"{', '.join(n for n, _, _ in fits)}: "
                              f"fit_lugre_from_log ({fitted}){road}", unit(key))

    for d in ("x", "y"):
        out[f"sigma0_{d}"] = Identified.not_excited(
            float(getattr(nominal, f"sigma0_{d}")),
            "the steady state holds σ0 only through σ0/κ (needs transients)", "1/m")
        out[f"sigma1_{d}"] = Identified.not_excited(
            float(getattr(nominal, f"sigma1_{d}")),
            "bristle damping shows only in transients; not fitted", "s/m")
        from_fits(f"sigma2_{d}", f"sigma2_{d}")
        from_fits(f"kappa_{d}", f"C_{d}", float(getattr(nominal, f"sigma0_{d}")))
    from_fits("mu_c", "mu_c")
    from_fits("v_s", "v_s")
    ratio = per.get("ratio_s", [])
    if ratio and "mu_c" in out and out["mu_c"].excited:
        v, rel, birge = _combine(ratio)
        mu_c = out["mu_c"]
        if birge <= 3.0:
            val = v * mu_c.value
            out["mu_s"] = Identified(val, val * math.hypot(rel, mu_c.sigma / mu_c.value), True,
                                     mu_c.evidence + " (μ_s/μ_c)", "-")
    if "mu_s" not in out:
        out["mu_s"] = Identified.not_excited(
            nominal.mu_s, notes.get("ratio_s", "friction curve not determined"), "-")
    out["alpha"] = Identified.not_excited(
        nominal.alpha, "Stribeck exponent: never fitted (needs sliding transients)", "-")
    return {k: out[k] for k in _LUGRE}


def identify_tires(logs: Sequence[pd.DataFrame], vehicle: Vehicle, *, lugre: bool = True
                   ) -> dict[str, Identified]:
    """Axle slip stiffnesses and the lumped LuGre values from the logs (module text).

    Args:
        logs: drive logs (``ref_`` columns are dropped unread).
        vehicle: the vehicle file: body geometry and inertia (the single-track equations),
            base values for what is not excited (``[stiffness]`` or the generic prior
            :meth:`StiffnessPrior.generic`, ``[tire]``).
        lugre: also fit the LuGre ``[tire]`` values (runs the pipeline once per log).

    Returns:
        ``cy_f``, ``cy_r`` (N/rad, axle total), ``cx_f``, ``cx_r`` (N per unit slip ratio,
        axle total), and with ``lugre`` the ``[tire]`` keys (σ0, σ1, σ2 in 1/m, s/m, s/m;
        κ 1/m; μ_s, μ_c; v_s m/s; α).
    """
    lg = _prepare(logs)
    prior = StiffnessPrior.for_vehicle(vehicle).nominal
    body = identify_body(logs, vehicle)["roll_gradient"]
    need = "cornering (transient yaw response in the linear range)"
    out = _linear_cornering(lg, vehicle, body.value, prior, need)
    for axle, key in ((0, "cx_f"), (1, "cx_r")):
        fit, why = _longitudinal(lg, vehicle, axle)
        out[key] = _stiffness_value(fit, 0, False, prior[axle], why, "N", "driving slip")
    if lugre:
        out.update(_lugre(logs, vehicle))
    return out
