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
from typing import NamedTuple

import numpy as np
from numba import njit

from vestim.params import check_ranges, pack


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
        turn_acc: 1 m/s², a_y is tested only while |v r| (low-passed) is below this: in a
            turn a slide's v̇_y reads as a bias (the simulator's ait_slippery: a 1.8 m/s
            sideslip building on ice was flagged as an a_y step and "corrected" away, v_y
            NRMS 1.1 → 62 %).
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
    turn_acc: float = 1.0
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


class ImuHealthKernelParams(NamedTuple):
    """:func:`imu_health_step`'s parameters: the vehicle's geometry (m: wheel radius, front
    and rear track, CG to front axle; from :class:`vestim.io.vehicle.VehicleBody`) and the
    :class:`ImuHealthParams` fields (SI, ``sat_n`` as a float)."""

    wheel_radius: float
    track_f: float
    track_r: float
    lf: float
    tau1: float
    tau2: float
    tau_s: float
    warm_s: float
    slip_abs: float
    slip_rel: float
    valid_hold: float
    e_max_acc: float
    e_max_gyro: float
    thr_acc: float
    thr_gyro: float
    turn_acc: float
    quiet_acc: float
    quiet_gyro: float
    tau_f: float
    tau_q: float
    quiet_s: float
    persist_s: float
    yaw_tol: float
    off_frac: float
    stuck_s: float
    motion_acc: float
    motion_gyro: float
    sat_n: float
    sat_floor_acc: float
    sat_floor_gyro: float
    range_acc: float
    range_gyro: float
    gap_s: float


class ImuHealthState(NamedTuple):
    """:func:`imu_health_step`'s state. Per channel (3,), order ax, ay, yaw_rate (m/s² or
    rad/s): ``mf`` the reading low-passed once, ``rf`` the reference low-passed once,
    ``e2`` the residual low-passed twice, ``rs2`` the reference low-passed twice, ``base``
    the residual's baseline, ``rslow`` and ``mslow`` the reference's and the reading's 1 s
    averages, ``bias`` 1.0 while a bias step is flagged and ``step`` its size, ``last`` the
    last reading, ``t_change`` when it last changed (s), ``ref_frozen`` the reference then,
    ``top`` the largest magnitude seen, ``run`` the count of identical samples at it,
    ``stuck`` and ``sat`` 1.0 while stuck / saturated, ``t_quiet`` when the drive last
    moved (s), ``t_above`` when the residual went above the threshold (s; NaN: it is not).
    Shared (1,): ``t_last`` the last sample's time, ``t_start`` the filters' (re)start
    time, ``v_filt`` the low-passed rear-axle speed (m/s), ``t_trusted`` the time from
    which the wheel reference is trusted (s), ``spread`` the low-passed front/rear speed
    spread (m/s) and ``yaw_diff`` the low-passed front-minus-rear wheel yaw rate (rad/s).
    NaN: not started."""

    mf: np.ndarray
    rf: np.ndarray
    e2: np.ndarray
    rs2: np.ndarray
    base: np.ndarray
    rslow: np.ndarray
    bias: np.ndarray
    step: np.ndarray
    last: np.ndarray
    t_change: np.ndarray
    ref_frozen: np.ndarray
    top: np.ndarray
    run: np.ndarray
    stuck: np.ndarray
    sat: np.ndarray
    t_quiet: np.ndarray
    t_above: np.ndarray
    mslow: np.ndarray
    t_last: np.ndarray
    t_start: np.ndarray
    v_filt: np.ndarray
    t_trusted: np.ndarray
    spread: np.ndarray
    yaw_diff: np.ndarray


_SHARED = ("t_last", "t_start", "v_filt", "t_trusted", "spread", "yaw_diff")


def imu_health_params(p: ImuHealthParams, wheel_radius: float, track_f: float, track_r: float,
                      lf: float) -> ImuHealthKernelParams:
    """:func:`imu_health_step`'s parameters from the validated ``p`` and the geometry (m:
    wheel radius, front and rear track, CG to front axle; from
    :class:`vestim.io.vehicle.VehicleBody`).

    Raises:
        ValueError: a geometry value is not finite and > 0.
    """
    for name, v in (("wheel_radius", wheel_radius), ("track_f", track_f),
                    ("track_r", track_r), ("lf", lf)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"IMU health geometry {name} = {v} must be finite and > 0 (m)")
    return pack(ImuHealthKernelParams, p, wheel_radius=wheel_radius, track_f=track_f,
                track_r=track_r, lf=lf)


def new_imu_state() -> ImuHealthState:
    """A fresh :class:`ImuHealthState`: every entry NaN (not started) but the largest
    magnitudes seen, 0."""
    s = ImuHealthState(*(np.full(1 if name in _SHARED else 3, np.nan)
                         for name in ImuHealthState._fields))
    s.top[:] = 0.0
    return s


@njit(cache=True, error_model="numpy")
def _of(j: int, a: float, b: float, c: float) -> float:
    """Channel ``j``'s value of (ax, ay, yaw_rate) = (a, b, c)."""
    return a if j == 0 else b if j == 1 else c


@njit(cache=True, error_model="numpy", inline="always")
def _restart(s: ImuHealthState, t: float, x0: float, x1: float, x2: float, r0: float,
             r1: float, r2: float, v: float) -> None:
    """Filters started at the readings ``x*`` and references ``r*`` of time ``t`` (s), the
    speed at ``v`` (m/s); the largest magnitudes seen are kept."""
    for j in range(3):
        xj, rj = _of(j, x0, x1, x2), _of(j, r0, r1, r2)
        s.mf[j] = xj
        s.rf[j] = rj
        s.e2[j] = xj - rj
        s.rs2[j] = rj
        s.base[j] = xj - rj
        s.rslow[j] = rj
        s.bias[j] = 0.0
        s.step[j] = 0.0
        s.last[j] = np.nan
        s.t_change[j] = t
        s.ref_frozen[j] = rj
        s.run[j] = 0.0
        s.stuck[j] = 0.0
        s.sat[j] = 0.0
        s.t_quiet[j] = t
        s.t_above[j] = np.nan
        s.mslow[j] = xj
    s.t_start[0] = t
    s.v_filt[0] = v
    s.t_trusted[0] = t  # reference trusted from now (filters start at the current values)


@njit(cache=True, error_model="numpy", inline="always")
def imu_health_step(p: ImuHealthKernelParams, s: ImuHealthState, t: float, ax: float,
                    ay: float, yaw_rate: float, w: np.ndarray, delta: np.ndarray,
                    out: np.ndarray, health: np.ndarray) -> None:
    """Health of one sample's a_x, a_y (m/s²) and yaw rate (rad/s) at time ``t`` (s),
    against the wheel speeds ``w`` (4,) rad/s (fl, fr, rl, rr) and the road-wheel angles
    ``delta`` (≥ 2: fl, fr) rad. ``out`` (3,) gets the readings (ax, ay, yaw_rate) with the
    faulty ones replaced, ``health`` (3,) 1.0 (healthy) or 0.0 (left out); ``s`` is
    advanced. A NaN reading passes through untouched; without wheel speeds only saturation
    is tested."""
    rad, tf, tr, lf = p.wheel_radius, p.track_f, p.track_r, p.lf
    wheels = not (np.isnan(w[0]) or np.isnan(w[1]) or np.isnan(w[2]) or np.isnan(w[3]))
    v = 0.5 * rad * (w[2] + w[3]) if wheels else 0.0
    r_w = rad * (w[3] - w[2]) / tr if wheels else 0.0
    dt = t - s.t_last[0]
    fresh = np.isnan(s.t_last[0]) or not (0.0 < dt <= p.gap_s)
    s.t_last[0] = t
    # references (ax, ay, yaw_rate); a_y's is set below from the yaw rate that goes out
    ref0, ref1, ref2 = 0.0, 0.0, 0.0
    if fresh:
        ref1 = v * (yaw_rate if not np.isnan(yaw_rate) else r_w)
        _restart(s, t, ax, ay, yaw_rate, 0.0, ref1, r_w, v)
        dt = 0.0
    a1 = dt / (p.tau1 + dt)
    a2 = dt / (p.tau2 + dt)
    el = t - s.t_start[0]
    a_s = dt / (min(p.tau_s, max(el, p.tau2)) + dt)
    a_f = dt / (p.tau_f + dt)
    a_q = dt / (p.tau_q + dt)
    # wheels agree? front speeds brought to the rear axle's (small sideslip neglected)
    if wheels:
        rr = r_w
        lo, hi = v, v
        for i in range(2):
            c = np.cos(delta[i])
            yw = 0.5 * tf if i == 0 else -0.5 * tf
            vi = (rad * w[i] - rr * lf * np.sin(delta[i])) / c + rr * yw if c > 0.1 else v
            lo, hi = min(lo, vi), max(hi, vi)
        cf = np.cos(0.5 * (delta[0] + delta[1]))
        r_f = rad * (w[1] - w[0]) / (tf * cf) if cf > 0.1 else r_w
        if fresh:
            s.spread[0], s.yaw_diff[0] = hi - lo, r_f - r_w
        else:  # low-passed: the wheel speeds' noise is not disagreement
            s.spread[0] += a2 * ((hi - lo) - s.spread[0])
            s.yaw_diff[0] += a2 * ((r_f - r_w) - s.yaw_diff[0])
        if s.spread[0] > p.slip_abs + p.slip_rel * abs(v) or abs(s.yaw_diff[0]) > p.yaw_tol:
            s.t_trusted[0] = t + p.valid_hold
    trusted = wheels and t >= s.t_trusted[0] and el >= p.warm_s
    # reference for a_x: derivative of the low-passed speed (= low-passed derivative)
    if wheels:
        vf_new = s.v_filt[0] + a1 * (v - s.v_filt[0])
        ref0 = (vf_new - s.v_filt[0]) / dt if dt > 0 else s.rf[0]
        s.v_filt[0] = vf_new
    ref2 = r_w
    for jj in range(3):
        j = 2 if jj == 0 else jj - 1  # order: yaw rate, ax, ay
        if j == 1:
            ref1 = v * out[2]
        xj = _of(j, ax, ay, yaw_rate)
        acc = j < 2
        bad = False
        replace_ref = False
        if not np.isnan(xj):
            # filters (the reference's only with wheel speeds)
            if wheels:  # a_x's reference is already the low-passed derivative
                s.rf[j] = ref0 if j == 0 else s.rf[j] + a1 * (_of(j, ref0, ref1, ref2) - s.rf[j])
            mf = s.mf[j] + a1 * (xj - s.mf[j])
            s.mf[j] = mf
            if wheels:
                s.e2[j] += a2 * ((mf - s.rf[j]) - s.e2[j])
                s.rs2[j] += a2 * (s.rf[j] - s.rs2[j])
                s.rslow[j] += a_q * (s.rs2[j] - s.rslow[j])
                m2 = s.e2[j] + s.rs2[j]  # the reading, low-passed twice
                s.mslow[j] += a_q * (m2 - s.mslow[j])
            # saturation: a flat top at the largest magnitude seen, or at the range
            floor = p.sat_floor_acc if acc else p.sat_floor_gyro
            rng = p.range_acc if acc else p.range_gyro
            ax_ = abs(xj)
            if xj == s.last[j] and ax_ >= s.top[j] and ax_ >= floor:
                s.run[j] += 1.0
            elif xj != s.last[j]:
                s.run[j] = 0.0
                s.sat[j] = 0.0
            s.top[j] = max(s.top[j], ax_)
            if s.run[j] >= p.sat_n - 1.0 or ax_ >= rng:
                s.sat[j] = 1.0
            elif ax_ < rng and xj != s.last[j]:
                s.sat[j] = 0.0
            # stuck: identical for stuck_s while the reference says otherwise
            if xj != s.last[j]:
                s.last[j] = xj
                s.t_change[j] = t
                s.ref_frozen[j] = s.rs2[j]
                s.stuck[j] = 0.0
            elif t - s.t_change[j] >= p.stuck_s and wheels and t >= s.t_trusted[0]:
                motion = p.motion_acc if acc else p.motion_gyro
                expect = s.rs2[j] + s.base[j]
                if abs(s.rs2[j] - s.ref_frozen[j]) > motion or abs(xj - expect) > motion:
                    s.stuck[j] = 1.0
            frozen = s.stuck[j] == 1.0 or s.sat[j] == 1.0
            # bias step against the baseline, tested while the reference is quiet
            if wheels:
                thr = p.thr_acc if acc else p.thr_gyro
                d = s.e2[j] - s.base[j]
                ok = trusted and not frozen and abs(d) < (p.e_max_acc if acc else p.e_max_gyro)
                # a_y only while nearly straight: in a turn a slide's v̇_y is not a bias
                ok = ok and (j != 1 or abs(s.rs2[1]) < p.turn_acc)
                moving = max(abs(s.rs2[j] - s.rslow[j]), abs(s.e2[j] + s.rs2[j] - s.mslow[j]),
                             abs(s.mf[j] - s.mslow[j]))
                if not ok or moving > (p.quiet_acc if acc else p.quiet_gyro):
                    s.t_quiet[j] = t
                quiet = t - s.t_quiet[j] >= p.quiet_s
                if s.bias[j] == 1.0:
                    if ok:
                        s.step[j] = d
                        if abs(d) < p.off_frac * thr:
                            s.bias[j] = 0.0
                elif ok and quiet and abs(d) > thr:
                    if np.isnan(s.t_above[j]):
                        s.t_above[j] = t
                    if t - s.t_above[j] >= p.persist_s:
                        s.bias[j] = 1.0
                        s.step[j] = d
                else:
                    s.t_above[j] = np.nan
                if s.bias[j] == 0.0 and ok:
                    ab = a_s if quiet else a_f
                    s.base[j] += ab * (s.e2[j] - s.base[j])
            bad = frozen or s.bias[j] == 1.0
            replace_ref = frozen
        out[j] = xj
        health[j] = 1.0
        if bad:
            health[j] = 0.0
            if replace_ref and wheels:
                out[j] = s.rs2[j] + s.base[j]
            elif not replace_ref:
                out[j] = xj - s.step[j]


@njit(cache=True, error_model="numpy")
def imu_health_kernel(p: ImuHealthKernelParams, s: ImuHealthState, t: np.ndarray,
                      ax: np.ndarray, ay: np.ndarray, yaw_rate: np.ndarray, omega: np.ndarray,
                      delta: np.ndarray, ax_out: np.ndarray, ay_out: np.ndarray,
                      r_out: np.ndarray, health: np.ndarray) -> None:
    """:func:`imu_health_step` over a block of samples at times ``t`` (n,) s: ``ax``,
    ``ay`` (m/s²), ``yaw_rate`` (rad/s) (n,), the wheel speeds ``omega`` (n, 4) rad/s and
    road-wheel angles ``delta`` (n, ≥ 2) rad. ``ax_out``/``ay_out``/``r_out`` (n,) get the
    readings with the faulty ones replaced, ``health`` (n, 3) 1.0 or 0.0 (columns ax, ay,
    yaw_rate). ``p`` from :func:`imu_health_params`, ``s`` from :func:`new_imu_state`,
    carried from block to block (a log in one call = sample by sample)."""
    out = np.empty(3)
    for k in range(t.shape[0]):
        imu_health_step(p, s, t[k], ax[k], ay[k], yaw_rate[k], omega[k], delta[k], out,
                        health[k])
        ax_out[k], ay_out[k], r_out[k] = out[0], out[1], out[2]
