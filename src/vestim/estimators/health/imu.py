"""IMU health (issue 15): a faulty a_x, a_y or yaw-rate reading is left out, not believed.

Per channel (ax, ay, yaw_rate) and sample, causally (the same kernel in
:meth:`Pipeline.run` and ``step``), against the **wheel-speed kinematic reference**

- a_x ≈ d(v)/dt with v = R (ω_rl + ω_rr)/2 (the rear axle's centre, unsteered),
- a_y ≈ v r (steady cornering; r the yaw rate used: the gyro's, or its replacement),
- r ≈ R (ω_rr − ω_rl) / track_r,

a reading is **faulty** when it is

- **saturated**: pinned at a rail, ``sat_n`` identical samples at the largest magnitude
  seen so far (and at least ``sat_floor``), or at/above a configured ``range``;
- **stuck**: exactly constant for ``stuck_s`` while the reference says it must differ
  (the reference moved by more than ``motion`` since it froze, or the frozen value is more
  than ``motion`` away from the reference): a dead (0) or frozen sensor;
- **bias-stepped**: the low-passed residual reading − reference moves away from its slow
  baseline by more than ``thr`` for ``persist_s``, while the drive is *quiet*. The reading
  and the reference go through the same low-pass filters (``tau1`` then ``tau2``), so the
  residual holds what the reference does not explain: the IMU bias, road grade (g sin θ)
  and bank, which change slowly and go into the baseline (``tau_s``), plus pitch / roll /
  sideslip-rate / tyre-lag terms, which follow the manoeuvre and reach several m/s² in
  transients (measured: up to 5 m/s² in a_x, 2.5 m/s² in a_y on the test logs). So the
  residual is tested only when neither the reading nor the reference has moved by more than
  ``quiet`` from its 1 s average (``tau_q``) for ``quiet_s``; while moving, the baseline
  follows the residual fast (``tau_f``). A bias step that begins in a manoeuvre is missed.

The reference is only trusted while the wheels agree (front speeds brought to the rear
axle's, within ``slip_abs + slip_rel v``; a spinning or locked wheel, ice, breaks it) and
held untrusted for ``valid_hold`` after they last disagreed (the filters are still full of
it); and, for the bias test of a channel, while its residual is below ``e_max`` (a larger
jump is wheel slip of all four wheels at once, not an IMU bias). Without a trusted reference
nothing new is flagged and the baselines are held.

A faulty reading is replaced: bias-stepped by the reading minus the estimated step (the
sensor's fast content is kept, the offset taken off); saturated or stuck by the low-passed
reference plus the channel's baseline (which carries grade and the sensor's own bias). While
left out, ``health`` is 0.0. A time gap over ``gap_s`` or a clock jump (``t`` not increasing)
restarts the filters (the largest magnitudes seen are kept).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from vestim.params import check_ranges

#: state rows: one per channel (ax, ay, yaw_rate), then the shared row
N_STATE = 18


@dataclass(frozen=True)
class ImuHealthParams:
    """Thresholds of the IMU health test, SI. Each value with its reason (figures measured
    on the 12 crossplant logs, the RAV4 log and the simulator, see
    ``tests/estimators/health/test_imu_faults.py``).

    Filters:
        tau1: 0.05 s, first low-pass of reading and reference (wheel speed noise 0.06 rad/s
            per sample would give ±5 m/s² derivative noise unfiltered).
        tau2: 0.1 s, second low-pass; with ``tau1`` a 0.3 m/s² step shows at 85 % in 0.3 s,
            within the 0.5 s target.
        tau_s: 3 s, slow baseline of the residual (grade and bank change over tens of
            metres: seconds) while quiet; tau_f: 0.3 s, the baseline while moving.
        tau_q: 1 s, quiet_acc 0.3 m/s², quiet_gyro 0.03 rad/s, quiet_s 0.5 s: "quiet" is
            reading and reference within these of their 1 s average for 0.5 s.
        persist_s: 0.1 s above the threshold before a bias is flagged (noise).
        warm_s: 1 s without new bias flags after a (re)start, while the baseline fills.
    Wheel reference:
        slip_abs, slip_rel: 0.5 m/s + 5 % of v: largest front/rear speed spread of free
            rolling wheels (noise, tyre slip of ~2 % under drive/brake, steering geometry);
            a spinning or locked wheel exceeds it by far.
        valid_hold: 0.5 s, the filters' memory (tau1 + tau2, ×3) after the wheels last
            disagreed.
        e_max_acc: 2 m/s², a residual jump above this is wheel slip (all wheels), not a bias.
        e_max_gyro: 0.2 rad/s, the same for the yaw rate.
    Bias step:
        thr_acc: 0.22 m/s², thr_gyro 0.03 rad/s: the smallest values (steps of 1.5× from
            0.15 / 0.02) with no false flag on the 12 crossplant logs, the RAV4 log and the
            simulator; measured margin: a flag appears at 0.85× (RAV4, x09), 0.90× (x10).
            Below the 0.3 m/s² step, which the filters show at 85 % after 0.3 s.
        yaw_tol: 0.1 rad/s, front and rear axle yaw rates from the wheels (low-passed) must
            agree within this for the reference to be trusted (one-sided slip).
        off_frac: 0.5, the fault ends when the step is back below half the threshold.
    Stuck:
        stuck_s: 0.1 s of exactly identical samples (a noisy sensor never repeats 20 samples;
            a frozen CAN value or dead sensor does).
        motion_acc: 0.5 m/s², motion_gyro: 0.05 rad/s: how far the reference must be from
            the frozen value (about 3× the filtered reference's noise and lag error).
    Saturation:
        sat_n: 5 identical samples at the largest magnitude seen (25 ms at 200 Hz).
        sat_floor_acc: 2 m/s², sat_floor_gyro: 0.3 rad/s: no rail below these (no IMU
            has a range that small; below them a flat top is the stuck test's).
        range_acc, range_gyro: configured sensor ranges (m/s², rad/s); inf: unknown, the
            flat top is detected alone.
    gap_s: 0.1 s, a gap longer than this restarts the filters (the pipeline's GAP_S order).
    """

    tau1: float = 0.05
    tau2: float = 0.1
    tau_s: float = 3.0
    warm_s: float = 1.0
    slip_abs: float = 0.5
    slip_rel: float = 0.05
    valid_hold: float = 0.5
    e_max_acc: float = 2.0
    e_max_gyro: float = 0.2
    thr_acc: float = 0.22
    thr_gyro: float = 0.03
    quiet_acc: float = 0.3
    quiet_gyro: float = 0.03
    tau_f: float = 0.3
    tau_q: float = 1.0
    quiet_s: float = 0.5
    persist_s: float = 0.1
    yaw_tol: float = 0.1
    off_frac: float = 0.5
    stuck_s: float = 0.1
    motion_acc: float = 0.5
    motion_gyro: float = 0.05
    sat_n: int = 5
    sat_floor_acc: float = 2.0
    sat_floor_gyro: float = 0.3
    range_acc: float = float("inf")
    range_gyro: float = float("inf")
    gap_s: float = 0.1

    def __post_init__(self) -> None:
        lower = ("valid_hold", "warm_s")
        check_ranges(self, "IMU health", nonnegative=lower,
                     positive=(f.name for f in fields(self) if f.name not in lower))
        if not self.off_frac < 1:
            raise ValueError(f"IMU health off_frac = {self.off_frac} must be < 1 (hysteresis)")
        if int(self.sat_n) != self.sat_n or self.sat_n < 2:
            raise ValueError(f"IMU health sat_n = {self.sat_n} must be an integer >= 2")


def imu_health_params(p: ImuHealthParams, wheel_radius: float, track_f: float, track_r: float,
                      lf: float) -> np.ndarray:
    """Pack for :func:`imu_health_kernel`: the thresholds of ``p`` per channel and the
    geometry (m: wheel radius, front and rear track, CG to front axle; from
    :class:`vestim.io.vehicle.VehicleBody`)."""
    for name, v in (("wheel_radius", wheel_radius), ("track_f", track_f),
                    ("track_r", track_r), ("lf", lf)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"IMU health geometry {name} = {v} must be finite and > 0 (m)")
    return np.array([
        wheel_radius, track_f, track_r, lf,                                  # 0-3
        p.tau1, p.tau2, p.tau_s, p.warm_s,                                   # 4-7
        p.slip_abs, p.slip_rel, p.valid_hold, p.off_frac,                    # 8-11
        p.e_max_acc, p.e_max_acc, p.e_max_gyro,                              # 12-14
        p.thr_acc, p.thr_acc, p.thr_gyro,                                    # 15-17
        p.quiet_acc, p.quiet_acc, p.quiet_gyro,                              # 18-20
        p.motion_acc, p.motion_acc, p.motion_gyro,                           # 21-23
        p.sat_floor_acc, p.sat_floor_acc, p.sat_floor_gyro,                  # 24-26
        p.range_acc, p.range_acc, p.range_gyro,                              # 27-29
        p.stuck_s, float(p.sat_n), p.gap_s,                                  # 30-32
        p.tau_f, p.tau_q, p.quiet_s, p.persist_s, p.yaw_tol,                 # 33-37
    ])


def new_imu_state() -> np.ndarray:
    """Kernel state (4, 16): rows ax, ay, yaw_rate (filtered reading, reference, residual,
    baselines, flags, frozen value, largest magnitude ...), then the shared row (last time,
    start time, filtered speed, end of the untrusted-reference hold). NaN: not started."""
    s = np.full((4, N_STATE), np.nan)
    s[:3, 11] = 0.0  # largest magnitude seen
    return s


# per-channel columns
_MF, _RF, _E2, _RS2, _BASE, _RSLOW, _BIAS, _STEP, _LAST, _TCH, _RFRZ, _TOP, _RUN, _STUCK, \
    _SAT, _QS, _AB, _MSLOW = range(18)


@njit(cache=True)
def _restart(state: np.ndarray, t: float, x: np.ndarray, ref: np.ndarray, v: float) -> None:
    for j in range(3):
        state[j, _MF] = x[j]
        state[j, _RF] = ref[j]
        state[j, _E2] = x[j] - ref[j]
        state[j, _RS2] = ref[j]
        state[j, _BASE] = x[j] - ref[j]
        state[j, _RSLOW] = ref[j]
        state[j, _BIAS] = 0.0
        state[j, _STEP] = 0.0
        state[j, _LAST] = np.nan
        state[j, _TCH] = t
        state[j, _RFRZ] = ref[j]
        state[j, _RUN] = 0.0
        state[j, _STUCK] = 0.0
        state[j, _SAT] = 0.0
        state[j, _QS] = t
        state[j, _AB] = np.nan
        state[j, _MSLOW] = x[j]
    state[3, 1] = t
    state[3, 2] = v
    state[3, 3] = t  # reference trusted from now (filters start at the current values)


@njit(cache=True)
def imu_health_kernel(t: np.ndarray, ax: np.ndarray, ay: np.ndarray, yaw_rate: np.ndarray,
                      omega: np.ndarray, delta: np.ndarray, prm: np.ndarray, state: np.ndarray,
                      ax_out: np.ndarray, ay_out: np.ndarray, r_out: np.ndarray,
                      health: np.ndarray) -> None:
    """Health of a_x, a_y (m/s²) and yaw rate (rad/s) over a block of samples at times ``t``
    (s), against the wheel speeds ``omega`` (n, 4) rad/s (fl, fr, rl, rr) and road-wheel
    angles ``delta`` (n, 4) rad. ``ax_out``/``ay_out``/``r_out`` get the readings with the
    faulty ones replaced, ``health`` (n, 3) 1.0 (healthy) or 0.0 (left out), columns ax, ay,
    yaw_rate. ``prm`` from :func:`imu_health_params`, ``state`` from :func:`new_imu_state`,
    carried from block to block (a log in one call = sample by sample). NaN readings pass
    through untouched; without wheel speeds only saturation is tested."""
    rad, tf, tr, lf = prm[0], prm[1], prm[2], prm[3]
    tau1, tau2, tau_s, warm = prm[4], prm[5], prm[6], prm[7]
    slip_abs, slip_rel, vhold, off = prm[8], prm[9], prm[10], prm[11]
    stuck_s, sat_n, gap = prm[30], prm[31], prm[32]
    tau_f, tau_q, qhold, persist, yaw_tol = prm[33], prm[34], prm[35], prm[36], prm[37]
    x = np.empty(3)
    ref = np.zeros(3)
    yw = np.array([0.5 * tf, -0.5 * tf, 0.5 * tr, -0.5 * tr])
    for k in range(t.shape[0]):
        tk = t[k]
        x[0], x[1], x[2] = ax[k], ay[k], yaw_rate[k]
        w = omega[k]
        wheels = not (np.isnan(w[0]) or np.isnan(w[1]) or np.isnan(w[2]) or np.isnan(w[3]))
        v = 0.5 * rad * (w[2] + w[3]) if wheels else 0.0
        r_w = rad * (w[3] - w[2]) / tr if wheels else 0.0
        dt = tk - state[3, 0]
        fresh = np.isnan(state[3, 0]) or not (0.0 < dt <= gap)
        state[3, 0] = tk
        # --- yaw rate first: a_y's reference uses the yaw rate that goes out
        if fresh:
            ref[0], ref[1], ref[2] = 0.0, v * (x[2] if not np.isnan(x[2]) else r_w), r_w
            _restart(state, tk, x, ref, v)
            dt = 0.0
        a1 = dt / (tau1 + dt)
        a2 = dt / (tau2 + dt)
        el = tk - state[3, 1]
        a_s = dt / (min(tau_s, max(el, tau2)) + dt)
        a_f = dt / (tau_f + dt)
        a_q = dt / (tau_q + dt)
        # wheels agree? front speeds brought to the rear axle's (small sideslip neglected)
        if wheels:
            rr = r_w
            lo, hi = v, v
            for i in range(2):
                c = np.cos(delta[k, i])
                vi = (rad * w[i] - rr * lf * np.sin(delta[k, i])) / c + rr * yw[i] if c > 0.1 \
                    else v
                lo, hi = min(lo, vi), max(hi, vi)
            cf = np.cos(0.5 * (delta[k, 0] + delta[k, 1]))
            r_f = rad * (w[1] - w[0]) / (tf * cf) if cf > 0.1 else r_w
            if fresh:
                state[3, 4], state[3, 5] = hi - lo, r_f - r_w
            else:  # low-passed: the wheel speeds' noise is not disagreement
                state[3, 4] += a2 * ((hi - lo) - state[3, 4])
                state[3, 5] += a2 * ((r_f - r_w) - state[3, 5])
            if state[3, 4] > slip_abs + slip_rel * abs(v) or abs(state[3, 5]) > yaw_tol:
                state[3, 3] = tk + vhold
        trusted = wheels and tk >= state[3, 3] and el >= warm
        # reference for a_x: derivative of the low-passed speed (= low-passed derivative)
        if wheels:
            vf_new = state[3, 2] + a1 * (v - state[3, 2])
            ref[0] = (vf_new - state[3, 2]) / dt if dt > 0 else state[0, _RF]
            state[3, 2] = vf_new
        ref[2] = r_w
        for jj in range(3):
            j = 2 if jj == 0 else jj - 1  # order: yaw rate, ax, ay
            if j == 1:
                ref[1] = v * r_out[k]
            xj = x[j]
            bad = False
            replace_ref = False
            if not np.isnan(xj):
                # filters (the reference's only with wheel speeds)
                if wheels:  # a_x's reference is already the low-passed derivative
                    state[j, _RF] = ref[0] if j == 0 else (
                        state[j, _RF] + a1 * (ref[j] - state[j, _RF]))
                mf = state[j, _MF] + a1 * (xj - state[j, _MF])
                state[j, _MF] = mf
                if wheels:
                    state[j, _E2] += a2 * ((mf - state[j, _RF]) - state[j, _E2])
                    state[j, _RS2] += a2 * (state[j, _RF] - state[j, _RS2])
                    state[j, _RSLOW] += a_q * (state[j, _RS2] - state[j, _RSLOW])
                    m2 = state[j, _E2] + state[j, _RS2]  # the reading, low-passed twice
                    state[j, _MSLOW] += a_q * (m2 - state[j, _MSLOW])
                # saturation: a flat top at the largest magnitude seen, or at the range
                floor, rng = prm[24 + j], prm[27 + j]
                ax_ = abs(xj)
                if xj == state[j, _LAST] and ax_ >= state[j, _TOP] and ax_ >= floor:
                    state[j, _RUN] += 1.0
                elif xj != state[j, _LAST]:
                    state[j, _RUN] = 0.0
                    state[j, _SAT] = 0.0
                state[j, _TOP] = max(state[j, _TOP], ax_)
                if state[j, _RUN] >= sat_n - 1.0 or ax_ >= rng:
                    state[j, _SAT] = 1.0
                elif ax_ < rng and xj != state[j, _LAST]:
                    state[j, _SAT] = 0.0
                # stuck: identical for stuck_s while the reference says otherwise
                if xj != state[j, _LAST]:
                    state[j, _LAST] = xj
                    state[j, _TCH] = tk
                    state[j, _RFRZ] = state[j, _RS2]
                    state[j, _STUCK] = 0.0
                elif tk - state[j, _TCH] >= stuck_s and wheels and tk >= state[3, 3]:
                    motion = prm[21 + j]
                    expect = state[j, _RS2] + state[j, _BASE]
                    if (abs(state[j, _RS2] - state[j, _RFRZ]) > motion
                            or abs(xj - expect) > motion):
                        state[j, _STUCK] = 1.0
                frozen = state[j, _STUCK] == 1.0 or state[j, _SAT] == 1.0
                # bias step against the baseline, tested while the reference is quiet
                if wheels:
                    d = state[j, _E2] - state[j, _BASE]
                    ok = trusted and not frozen and abs(d) < prm[12 + j]
                    moving = max(abs(state[j, _RS2] - state[j, _RSLOW]),
                                 abs(state[j, _E2] + state[j, _RS2] - state[j, _MSLOW]),
                                 abs(state[j, _MF] - state[j, _MSLOW]))
                    if not ok or moving > prm[18 + j]:
                        state[j, _QS] = tk
                    quiet = tk - state[j, _QS] >= qhold
                    if state[j, _BIAS] == 1.0:
                        if ok:
                            state[j, _STEP] = d
                            if abs(d) < off * prm[15 + j]:
                                state[j, _BIAS] = 0.0
                    elif ok and quiet and abs(d) > prm[15 + j]:
                        if np.isnan(state[j, _AB]):
                            state[j, _AB] = tk
                        if tk - state[j, _AB] >= persist:
                            state[j, _BIAS] = 1.0
                            state[j, _STEP] = d
                    else:
                        state[j, _AB] = np.nan
                    if state[j, _BIAS] == 0.0 and ok:
                        ab = a_s if quiet else a_f
                        state[j, _BASE] += ab * (state[j, _E2] - state[j, _BASE])
                bad = frozen or state[j, _BIAS] == 1.0
                replace_ref = frozen
            if j == 0:
                out = ax_out
            elif j == 1:
                out = ay_out
            else:
                out = r_out
            out[k] = xj
            health[k, j] = 1.0
            if bad:
                health[k, j] = 0.0
                if replace_ref and wheels:
                    out[k] = state[j, _RS2] + state[j, _BASE]
                elif not replace_ref:
                    out[k] = xj - state[j, _STEP]
