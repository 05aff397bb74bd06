"""Cross-channel sanity checks of a log against its vehicle, run before estimation.

:func:`~vestim.io.log.validate_log` checks each channel on its own (rpm, degrees, g). A log
can pass those and still be wrong in a way no single channel shows: a yaw rate with the
wrong sign, ``ax`` and ``ay`` in g, ``az`` with gravity removed, a roll rate in deg/s, wheel
torques with the wrong sign, a y axis that points right. The estimators then return numbers
that look fine and are not (issue 14 measured 63–172 % errors). This module compares the
channels with each other through the vehicle's geometry, using physics that holds on every
road car:

========================  ==============================================================
relation                  why it holds
========================  ==============================================================
ay ≈ v·r                  steady turning: lateral acceleration is speed times yaw rate
                          (plus the slow v̇_y, and g·φ from roll: ratio 0.9–1.2)
R·(ω_r − ω_l) ≈ r·track   the outer wheels travel further; the wheels' left/right labels
                          are physical, so this fixes the sign of r (and of y)
r ≈ v·δ/L · u             kinematic steering with an understeer factor u = 1/(1+K·v²),
                          0.3–1.3 for a road car below the limit
∫ax dt ≈ R·Δω             the speed change over 1 s from the accelerometer and the wheels
median(ax − R·ω̇) ≈ 0     over the whole log on level roads: an IMU pitched by θ adds
                          −g·sin θ to every window (a road grade adds g·sin(grade), for
                          a while)
Σ torque ≈ m·R·a          the wheel torques accelerate the car, a = R·ω̇ (each wheel's
                          share > 0)
∫p dt ≈ k·Δay             the body rolls outward: roll gradient k = 0.002–0.021 rad per m/s²
median az ≈ +9.81         specific force at rest is +g along z (spec)
R·ω ≈ gnss_speed          a speed channel agrees with the wheels (rolling radius ± 8 %)
========================  ==============================================================

A log without wheel speeds (docs/fewer-sensors.md) takes v from ``vehicle_speed`` or
``gnss_speed`` and gets every check that does not need the wheels.

Every relation is evaluated on 0.5 s bin means (or 1 s windows) where it is well excited
(speed, turning, acceleration) and where the four wheels agree (no spinning or locked wheel,
see :data:`SPREAD_BASE`), as a median of per-bin ratios or a robust least-squares slope.
Each threshold below sits between the range a clean log reaches and the value the mistake
gives, with the margin stated. Strong evidence gives an error (all errors of a log are raised
together in one :class:`~vestim.errors.LogFormatError`); evidence that is suggestive but not
conclusive gives a warning; a relation that is not excited in the log (or whose channels the log lacks)
cannot be evaluated: :func:`gate` lists it, with the reason, in :attr:`GateReport.not_run`,
which every entry point writes into the output metadata (``checks_not_run``).
The table of mistakes and the exact messages is ``docs/input-checks.md``.

:func:`gate` is the one input gate of every entry point (``vestim estimate``, ``batch``,
``calibrate``, ``report`` and :func:`vestim.estimate`); :func:`validate_sample` is its
per-sample form for :meth:`vestim.pipeline.Pipeline.step`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy.ndimage import uniform_filter1d

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io.calibration import correct_columns
from vestim.io.log import (
    ACCEL_MAX,
    OMEGA_MAX,
    RATE_MAX,
    ROAD_WHEEL_ANGLE_MAX,
    STEERING_WHEEL_ANGLE_MAX,
    road_wheel_angles,
    validate_log,
)
from vestim.io.vehicle import Vehicle

__all__ = ["SAMPLE_RANGES", "Finding", "GateReport", "NotRun", "check_log", "find_problems",
           "gate", "validate_sample"]

GATE_ROWS = 720_000
"""The checks of :func:`gate` run on the first this many rows (1 h at 200 Hz; a whole log
below that): they need the rows in memory, the estimate of a long log does not."""

Severity = Literal["error", "warning"]
OMEGAS = ", ".join(ch.WHEEL_SPEEDS)

BIN_S = 0.5
"""s; bin length of the bin means (a low-pass that removes sensor noise and most of the lag
between steering, yaw and lateral acceleration)."""
WINDOW_S = 1.0
"""s; length of the windows over which speed changes and roll angles are compared."""
MIN_BINS = 10
"""Minimum number of excited bins (5 s of turning) or windows for a relation to count."""
MAJORITY = 0.8
"""Share of the excited bins that must agree on a sign before a sign error is reported; a
clean log has every bin on one side except during the rare transients at the limit."""

V_MIN = 5.0
"""m/s; lateral and steering relations are used above this speed (below it kinematic
steering and tire slip angles are not small)."""
V_MIN_YAW = 3.0
"""m/s; wheel-speed differences are used above this speed."""
AY_MIN = 1.0
"""m/s²; least |v·r| of a bin for the lateral relation: the accelerometer's bias (≤ 0.1
m/s²) and bank angle are then at most 10 % of it."""
STEADY_YAW = 0.25
"""Largest range of r over a bin and its neighbours (1.5 s), as a share of the bin's |r|,
for a bin to count as a quasi-steady turn. ay = v̇_y + v·r, and v·r stands for
ay only where v̇_y is small: a 1 Hz steering chirp at 34 m/s (campaign s1_001) reads
ay/(v·r) = 0.22 over all its turning bins, in the band of a km/h speed channel, with no
steady bin at all. The unit errors (ay in g, a speed in km/h) are therefore judged on the
steady bins only; transient bins alone give a warning."""
YAW_MIN = 0.05
"""rad/s; least |r| of a bin for the wheel-speed difference (0.05 rad/s gives 0.08 m/s of
speed difference across a 1.6 m track, 10× the difference the wheel-speed noise leaves in a
0.5 s bin mean)."""
AY_MAX_YAW = 4.0
"""m/s²; most |v·r| of a bin for the wheel-speed difference. Beyond about 0.4 g the inner
wheels unload and, with the drive torque shared equally, slip several per cent more than the
outer ones, which can cancel the geometric difference (vestim's own simulator at 0.8 g shows
half of it, and on a steered unloaded front wheel the opposite sign)."""
STEER_MIN = 0.05
"""rad/s; least |v·δ/L| of a bin for the steering relation."""
SPREAD_BASE = 0.04
"""A bin counts as free of wheel slip when (max − min)/median of its four wheel speeds is at
most SPREAD_BASE + 1.3·track·|r|/v: the geometric spread of a turn (track·|r|/v, with a 30 %
allowance for the steered front wheels' path) plus 4 % for the slip ratios of ordinary
driving. A spinning or locking wheel (slip ratio ≥ 0.1) leaves the bin out."""

LAT_NORMAL = (0.5, 2.0)
"""Plausible range of ay/(v·r) (outside it is a warning): the clean logs read 0.93–1.19 (roll
adds g·φ ≈ +5–15 %)."""
LAT_G = (0.04, 0.2)
"""ay/(v·r) of a log whose ay is in g: (0.93–1.19)/9.81 = 0.095–0.12, here with a margin of
two below and 1.6 above; 0.2 stays below a km/h speed channel's 0.26 (see KMH_LAT)."""
SIGN_RATIO = 0.3
"""|ratio| a negative median ratio must reach to count as a sign error (a flipped channel
gives about −1; noise about zero gives medians near 0)."""
YAW_NORMAL = (0.4, 2.5)
"""Plausible range of R·Δω/(track·r); outside it is a warning. The clean logs read 0.96–1.09
(load-dependent rolling radii and slip differences move it; vestim's simulator shows 0.5 at
0.8 g, hence AY_MAX_YAW)."""
YAW_DEG = (0.5 * math.pi / 180, 2.0 * math.pi / 180)
"""R·Δω/(track·r) or ay/(v·r) in this band (π/180 = 0.0175 within a factor of two) means
yaw_rate is in deg/s: no other mistake scales either relation by 1/57 (g gives 1/9.81, a
wheel-speed unit scales both relations in opposite directions)."""
STEER_LOW = (0.12, 0.25)
"""r/(v·δ/L) below the first value is an error, between the two a warning. The clean logs read
0.69–1.03; understeer at the friction limit can halve it. δ in degrees gives 1/57 of the clean
value (0.009–0.02), a steering-wheel angle in ``delta`` 1/ratio (0.03–0.07)."""
STEER_HIGH = (3.0, 5.0)
"""r/(v·δ/L) above the first value is a warning, above the second an error: a road car never
yaws several times faster than kinematic steering (oversteer adds at most some 30 %)."""
LON_G = 0.25
"""Slope of ∫ax dt on R·Δω below which ``ax`` looks like g: a log in g gives about 0.1
(0.07–0.11), the clean logs 0.73 (the RAV4's phone IMU) to 1.08."""
LON_G_SPEED = 0.15
"""LON_G for a log whose speed is a speed channel (no wheel speeds): there a speed in km/h
also lowers the slope, to (0.73–1.08)/3.6 = 0.2–0.3, so the g limit moves down to 0.15
(ax in g: 0.07–0.11)."""
LON_MAX_REL_SE = 0.1
"""Largest relative standard error of that slope: clean logs and logs in g reach 0.024, a
braking on μ = 0.25 with ABS (the wheels cycle while the car decelerates steadily) gives a
slope near 0 with a standard error 5–30 times larger."""
LON_MIN_STEP = 1.0
"""m/s; least |R·Δω| over a 1 s window for the longitudinal relation."""
TORQUE_MIN_STEP = 0.5
"""m/s; least |R·Δω| over a 1 s window for the torque relation."""
T_STAT = 5.0
"""|slope / standard error| a slope of the wrong sign must reach to be an error."""
TORQUE_SCALE = 10.0
"""The wheel torques' sum over m·R·a (positive, |t| ≥ T_STAT) beyond a factor 10 of 1 is an
error: clean logs read 0.97–1.20 (crossplant x10–x12 1.06–1.08, the campaign's 14 logs with
enough acceleration 0.97–1.20, sim:accel_brake 1.03; rolling resistance, drag and grade are
the fit's intercept); kN·m read as N·m gives 0.001, N·m declared as kN·m 1000. Wheel
speeds in m/s (R ≈ 0.3) move it only by 1/R ≈ 3, which the wheel checks name."""
ROLL_MAX = 0.06
"""rad per m/s²; roll gradient above which ``roll_rate`` looks like deg/s. Road cars roll
1–12°/g (0.002–0.021 rad per m/s²; the clean crossplant logs 0.011–0.016, vestim's simulator
0.003); deg/s multiplies the figure by 57.3 (0.1–1.2)."""
ROLL_WINDOW_S = 2.0
"""s; second window of the roll relation (long enough for a slow ramp steer to change ay)."""
ROLL_MIN_STEP = 0.5
"""m/s²; least |Δay| over a window for the roll relation (the gyro bias, up to
0.005 rad/s, is the fit's intercept)."""
AZ_TOL = 2.0
"""m/s²; a median az within 9.81 ± 2 is normal (a 20 % grade and body heave reach 0.5)."""
AZ_NO_GRAVITY = 0.5
"""m/s²; a median |az| below this means gravity was subtracted (g units read 0.5–1.5)."""
WHEEL_RATIO = 2.0
"""A wheel whose speed is a constant factor ≥ 2 away from the other three's median is in
another unit (rpm 9.55, m/s 1/R ≈ 3); a spinning wheel varies, see WHEEL_SPREAD."""
WHEEL_SPREAD = 0.1
"""Largest interquartile range of ln(ω_i / others) for a constant factor."""
WHEEL_ALONE = 1.15
"""A wheel a constant factor ≥ 1.15 away from the other three's median and from its axle
mate alone is in another unit too (mph read as rad/s: 2.237·R = 0.74 at R = 0.33 m; km/h
3.6·R = 1.19). Clean logs stay within 1.03 of the others where the axle mates agree (x07's
turn 1.026, x04's locked wheel 0.947 with IQR 0.058, RAV4 1.002); a driven axle spinning
together (x01's front wheels 1.12, IQR 0.03) is not one wheel alone."""
SCALE_EVIDENCE = 0.5
"""A wheel-speed scale estimate e supports a wrong-unit factor c when ln e / ln c lies in
[0.5, 2]: closer to c than to 1 on a log scale, and not beyond c by more than c is from 1.
The clean logs' two estimates (lateral, yaw) read 0.96–1.11; one of them may support
(sim:dlc_snow's lateral 1.11 against c = 1.19: ln e / ln c = 0.63), never both, which is why
only both together count, and only as a warning."""
GNSS_TOL = 0.08
"""R·ω / gnss_speed (or vehicle_speed) of a clean log is within 8 % of 1 (rolling-radius
uncertainty; RAV4: 1.008); beyond it is a warning."""
KMH_SPEED_TOL = 0.15
"""|ln(3.6·R·ω / speed)| within which a speed channel (gnss_speed, vehicle_speed) counts as
km/h; the clean RAV4 reads ln 1.008 = 0.008, a km/h column ln(1/3.6) = −1.28 from 1."""
KMH_LAT = (0.2, 0.45)
"""ay/(v·r) in this band, on a log whose speed comes from gnss_speed or vehicle_speed (no
wheel speeds), means that channel is in km/h: the clean 0.93–1.19 divided by 3.6 is
0.26–0.33. (g units of ay give 0.095–0.12, below the band: LAT_G stops at 0.2.)"""
KMH_MIN = 0.1
"""|ln(3.6·R)| below this (R between 0.251 and 0.307 m) makes km/h within 10 % of rad/s:
indistinguishable and nearly harmless, so not reported."""
PITCH_AY_MAX = 2.0
"""m/s²; most |v·r| of a window's two bins for the pitch check: in a turn ax = v̇_x − r·v_y,
and the sideslip term r·v_y = a_y·β is not in R·ω̇ (vestim's simulator's step steer reads
+0.53 m/s² over all its 14 windows, −0.005 over the two below 2 m/s²)."""
PITCH_ACC_MAX = 1.0
"""m/s²; most |R·Δω|/Δt of a window for the pitch check: near-steady driving, where a gain
error of ax (the RAV4's phone reads 0.73 × the wheels' speed change) or wheels that lag the
car under braking move the difference little (a gain of 0.73 by at most 0.27 m/s² per
window)."""
PITCH_WARN = 0.6
"""m/s²; |median(ax − R·ω̇)| over the near-steady 1 s windows (v ≥ V_MIN_YAW, |v·r| ≤
PITCH_AY_MAX, |R·ω̇| ≤ PITCH_ACC_MAX, no wheel slip) from which ax, az look pitched: a
warning. The clean logs (level roads) read −0.10 to +0.16: crossplant x08 +0.036 and x10
−0.048 (the other ten have fewer than MIN_BINS such windows), the 29 campaign logs with
wheel speeds, ax and enough steady driving −0.095 to +0.163 (their accelerometer biases
reach 0.14), the RAV4 +0.017 (95 windows), vestim's simulator's accel_brake +0.017. An IMU
pitched 10° reads −1.66 to −1.74 (x10 −1.743, RAV4 −1.656, accel_brake −1.684; −10° on x10
+1.647), 5° −0.90 and 3° −0.56 (x10). 0.6 m/s² is 3.5° of pitch: 3.7 times the clean logs'
largest figure, a third of the 10° figure, and the mean grade (6 %) of a log driven up or
down a long motorway climb the whole time; a steeper road held for the whole log gives
this warning too, which is why it is a warning (see PITCH_ERROR)."""
PITCH_ERROR = 3.0
"""m/s²; the same |median| from which ax, az are refused: g·sin 17.8°, a 32 % grade held
for the whole log, which no public road has (the steepest streets reach 35 % for a few
hundred metres); an IMU pitched ≥ 18°, or an axis mix-up (az in ax reads about +9.8)."""


@dataclass(frozen=True)
class Finding:
    """One problem found in a log.

    Attributes:
        channel: the column(s) concerned, comma-separated (e.g. ``"ay, yaw_rate"``).
        severity: ``"error"`` (strong evidence; :func:`check_log` raises) or ``"warning"``.
        message: what was found, the likely cause and the fix.
        evidence: the figure the decision rests on (a ratio or slope; see ``check``).
        check: the relation that found it (``lateral``, ``yaw_wheels``, ``steering``,
            ``longitudinal``, ``torque``, ``roll``, ``gravity``, ``wheels``, ``speed``,
            ``pitch``).
    """

    channel: str
    severity: Severity
    message: str
    evidence: float
    check: str

    def as_dict(self) -> dict[str, str | float | None]:
        """Plain dict for JSON metadata (a non-finite evidence becomes None)."""
        return {"channel": self.channel, "severity": self.severity, "message": self.message,
                "evidence": self.evidence if math.isfinite(self.evidence) else None,
                "check": self.check}


@dataclass(frozen=True)
class NotRun:
    """A cross-channel check that could not be evaluated on a log.

    Attributes:
        check: the relation (the names of :attr:`Finding.check`).
        reason: why: ``"not excited: …"`` (the log has too little turning, acceleration,
            speed …, with the threshold) or ``"no … channel"``.
    """

    check: str
    reason: str

    def as_dict(self) -> dict[str, str]:
        """Plain dict for JSON metadata."""
        return {"check": self.check, "reason": self.reason}


@dataclass(frozen=True)
class GateReport:
    """What :func:`gate` found in a log that passed it.

    Attributes:
        warnings: the findings of weak evidence (the errors were raised).
        not_run: the checks that could not be evaluated, each with its reason.
    """

    warnings: tuple[Finding, ...]
    not_run: tuple[NotRun, ...]

    @property
    def not_excited(self) -> tuple[str, ...]:
        """The checks that could not run for lack of excitation (their channels present)."""
        return tuple(n.check for n in self.not_run if n.reason.startswith("not excited"))

    def metadata(self, extra_warnings: list[dict[str, Any]] | None = None) -> dict[str, str]:
        """Output metadata (JSON strings): ``warnings`` (the findings, then ``extra_warnings``,
        e.g. the pipeline's consistency monitor) and ``checks_not_run`` (check and reason)."""
        warn = [w.as_dict() for w in self.warnings] + list(extra_warnings or [])
        return {"warnings": json.dumps(warn, ensure_ascii=False),
                "checks_not_run": json.dumps([n.as_dict() for n in self.not_run],
                                             ensure_ascii=False)}


def gate(df: pd.DataFrame, vehicle: Vehicle, *, source: str = "log") -> GateReport:
    """The input gate of every entry point: :func:`validate_log` and the cross-channel checks
    on the first :data:`GATE_ROWS` rows; raise on errors.

    Args:
        df: a measured log (spec channels, SI units); it is not modified.
        vehicle: its vehicle (wheel_radius, track_f, track_r, lf + lr, mass, steering_ratio
            are used).
        source: prefix of the messages (the file name).

    Returns:
        The warnings (weak evidence) and the checks that could not run, with the reason.

    Raises:
        LogFormatError: one message listing every error found (strong evidence), each
            naming the channel, the likely cause and the fix.
    """
    head = df if len(df) <= GATE_ROWS else df.iloc[:GATE_ROWS]
    validate_log(head, require=["measured"], wheel_radius=vehicle.body.wheel_radius,
                 source=source)
    findings, not_run = _run_checks(head, vehicle)
    errors = [f for f in findings if f.severity == "error"]
    if errors:
        if len(errors) == 1:
            raise LogFormatError(f"{source}: {errors[0].message}")
        listing = "; ".join(f"({i}) {f.message}" for i, f in enumerate(errors, 1))
        raise LogFormatError(f"{source}: {len(errors)} problems: {listing}")
    return GateReport(tuple(f for f in findings if f.severity == "warning"), tuple(not_run))


def check_log(df: pd.DataFrame, vehicle: Vehicle, *, source: str = "log") -> list[Finding]:
    """:func:`gate`'s warnings (it raises :class:`~vestim.errors.LogFormatError` on errors)."""
    return list(gate(df, vehicle, source=source).warnings)


def find_problems(df: pd.DataFrame, vehicle: Vehicle) -> list[Finding]:
    """Every finding (errors and warnings) of the cross-channel checks, in check order.

    Raises nothing for a log that passes ``validate_log(require=["measured"])``; torques, az,
    roll_rate, gnss_speed and vehicle_speed are used when present, ax when present.
    """
    return _run_checks(df, vehicle)[0]


_NO_EXCITATION = {
    "wheels": f"not excited: fewer than {MIN_BINS} half-second bins at ≥ {V_MIN_YAW:g} m/s",
    "longitudinal": (f"not excited: fewer than {MIN_BINS} one-second windows with a speed "
                     f"change ≥ {LON_MIN_STEP:g} m/s and a well-determined slope"),
    "lateral": (f"not excited: fewer than {MIN_BINS} half-second bins of turning with "
                f"v ≥ {V_MIN:g} m/s, |v·r| ≥ {AY_MIN:g} m/s² and no wheel slip"),
    "yaw_wheels": (f"not excited: fewer than {MIN_BINS} half-second bins with "
                   f"|yaw_rate| ≥ {YAW_MIN:g} rad/s at v ≥ {V_MIN_YAW:g} m/s and "
                   f"|v·r| ≤ {AY_MAX_YAW:g} m/s²"),
    "steering": (f"not excited: fewer than {MIN_BINS} half-second bins with "
                 f"|v·δ/L| ≥ {STEER_MIN:g} rad/s at v ≥ {V_MIN:g} m/s"),
    "roll": (f"not excited: fewer than {MIN_BINS} windows with |Δay| ≥ {ROLL_MIN_STEP:g} "
             "m/s² and a determined roll gradient"),
    "torque": (f"not excited: fewer than {MIN_BINS} one-second windows with a speed change "
               f"≥ {TORQUE_MIN_STEP:g} m/s"),
    "pitch": (f"not excited: fewer than {MIN_BINS} one-second windows of near-steady driving "
              f"(v ≥ {V_MIN_YAW:g} m/s, |v·r| ≤ {PITCH_AY_MAX:g} m/s², |R·Δω|/Δt ≤ "
              f"{PITCH_ACC_MAX:g} m/s², no wheel slip)"),
}
"""The reason :class:`NotRun` gives for a check whose channels are there but not excited."""


def _run_checks(df: pd.DataFrame, vehicle: Vehicle) -> tuple[list[Finding], list[NotRun]]:
    """The findings in check order, and the checks that could not be evaluated."""
    s = _Signals(df, vehicle)
    out: list[Finding] = []
    out += _gravity(s)
    wheels_ran = _wheels_each_other(s, out)
    lon = _longitudinal(s, out)
    pitch_ran = _pitch(s, out)
    lat = _ratio_check(s.lat_x, s.ay, s.lat_sel)
    yaw = _ratio_check(s.r, s.yaw_y, s.yaw_sel)
    steer = _ratio_check(s.steer_x, s.r, s.steer_sel)
    roll: _Roll | None = None
    if _yaw_scale(s, lat, yaw, out):  # yaw_rate in deg/s: every relation with r is off by 57
        torque_ran = _torque(s, out)
    else:
        n_before = len(out)
        steady = _ratio_check(s.lat_x, s.ay, s.steady_sel)
        ay_in_g = _lateral_scale(s, lat, steady, lon, out)
        speed_kmh = any(f.check == "speed" for f in out[n_before:])
        roll = _roll(s, ay_in_g, out)
        _signs(s, lat, yaw, steer, roll, out)
        if not speed_kmh:  # a speed in km/h also makes δ look 3.6 times too large
            _steering_scale(s, steer, out)
        torque_ran = _torque(s, out)
        _wheel_scale(s, lat, yaw, roll, ay_in_g, lon, out)
    cols = set(df.columns)
    missing = {
        "gravity": None if "az" in cols else "no az channel",
        "wheels": None if s.has_wheels else "no wheel-speed channels",
        "longitudinal": None if "ax" in cols else "no ax channel",
        "yaw_wheels": None if s.has_wheels else "no wheel-speed channels",
        "roll": None if "roll_rate" in cols else "no roll_rate channel",
        "torque": None if set(ch.TORQUES) <= cols else "no wheel-torque channels",
        "pitch": ("no ax channel" if "ax" not in cols else
                  None if s.has_wheels else "no wheel-speed channels"),
    }
    ran = {"gravity": "az" in cols, "wheels": wheels_ran, "longitudinal": lon is not None,
           "lateral": lat is not None, "yaw_wheels": yaw is not None,
           "steering": steer is not None, "roll": roll is not None, "torque": torque_ran,
           "pitch": pitch_ran}
    not_run = [NotRun(check, missing.get(check) or _NO_EXCITATION[check])
               for check, done in ran.items() if not done]
    return out, not_run


# --- one sample (Pipeline.step) ---------------------------------------------------------------

TORQUE_MAX = 50_000.0
"""N·m; |net wheel torque| of one wheel: a car's reaches 2–5 kN·m (brake or drive), a 40 t
truck's some 20 kN·m; a torque in N·mm, or an overflowing CAN signal, lands beyond."""
SPEED_MAX = 150.0
"""m/s (540 km/h); |gnss_speed| and |vehicle_speed| of a road vehicle are below it."""

SAMPLE_RANGES: dict[str, tuple[float, float, str]] = {
    **{c: (-OMEGA_MAX, OMEGA_MAX, "rad/s") for c in ch.WHEEL_SPEEDS},
    **{c: (-TORQUE_MAX, TORQUE_MAX, "N·m") for c in ch.TORQUES},
    **{c: (-ACCEL_MAX, ACCEL_MAX, "m/s²") for c in ("ax", "ay", "az")},
    **{c: (-RATE_MAX, RATE_MAX, "rad/s") for c in ("yaw_rate", "roll_rate", "pitch_rate")},
    **{c: (-ROAD_WHEEL_ANGLE_MAX, ROAD_WHEEL_ANGLE_MAX, "rad")
       for c in (*ch.ROAD_WHEEL_ANGLES, ch.DELTA)},
    ch.STEERING_WHEEL_ANGLE: (-STEERING_WHEEL_ANGLE_MAX, STEERING_WHEEL_ANGLE_MAX, "rad"),
    **{c: (-SPEED_MAX, SPEED_MAX, "m/s") for c in ch.SPEED_SOURCES},
}
"""Physical range (low, high, unit) of each measured channel of one sample: the whole-log
limits of :func:`~vestim.io.log.validate_log` (ω 400 rad/s, δ π/2 rad, steering wheel 4π
rad, rates 5 rad/s, accelerations 60 m/s²), which lie beyond any road car in SI units, plus
:data:`TORQUE_MAX` and :data:`SPEED_MAX`. ``az`` reads about +9.81 and is within ±60 too."""


class Sample(dict[str, float]):
    """A sample after :func:`validate_sample`: channel → float (NaN where a value was
    rejected); :attr:`rejected` says, per rejected channel, what its value was."""

    rejected: dict[str, str]


def validate_sample(sample: Mapping[str, Any]) -> Sample:
    """One sample of a live feed checked for type, finiteness and physical range.

    Every measured channel (:data:`SAMPLE_RANGES`) becomes a float. A value that is not a
    real number (``None``, a string, a list, a bool) or lies outside its channel's range is
    replaced by NaN, as a dropped value: :meth:`vestim.pipeline.Pipeline.step` then holds the
    channel's last good value (at most ``HOLD_S``) and flags the row "input held", or raises
    :class:`~vestim.errors.LogFormatError` naming the channel. NaN and inf stay as they are
    (the same hold); a NaN ``gnss_speed`` is "no fix". Channels vestim does not read
    (``ref_*``, unknown names) are left out.

    Args:
        sample: channel name → value (SI units, the log format's names).

    Returns:
        The cleaned sample; its ``rejected`` maps each replaced channel to its value and the
        reason (for the error message).

    Raises:
        LogFormatError: ``t`` is missing or not a real number.
    """
    out = Sample()
    out.rejected = {}
    for key, value in sample.items():
        rng = SAMPLE_RANGES.get(key)
        if rng is None:
            if key == ch.T:
                try:
                    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                        raise TypeError
                    out[key] = float(value)
                except (OverflowError, TypeError, ValueError):
                    raise LogFormatError(f"sample t = {str(value)[:40]!r}: t must be a real "
                                         "number, in seconds") from None
            continue
        if type(value) is float:  # the usual case, checked first (a live loop's cost)
            v = value
        elif isinstance(value, bool) or not isinstance(value, int | float | np.number):
            out[key] = math.nan
            out.rejected[key] = f"{value!r} (not a number)"
            continue
        else:
            try:
                v = float(value)
            except (OverflowError, TypeError, ValueError):  # a huge int, a complex number
                v = math.inf
        lo, hi, unit = rng
        if lo <= v <= hi or v != v:  # in range, or NaN (a dropped value; no fix)
            out[key] = v
        else:
            out[key] = math.nan
            out.rejected[key] = f"{value!r} {unit}, outside [{lo:.4g}, {hi:.4g}] {unit}"
    return out


# --- signals ---------------------------------------------------------------------------------


def _f(df: pd.DataFrame, name: str) -> np.ndarray:
    return df[name].to_numpy(dtype=np.float64)


class _Signals:
    """Bin means and window differences shared by the checks.

    The speed ``v`` is R·(median of the four wheel speeds) when the log has them; a log
    without ``omega_*`` (docs/fewer-sensors.md) uses ``vehicle_speed``, else ``gnss_speed``
    interpolated between its fixes, and gets no wheel checks."""

    def __init__(self, df: pd.DataFrame, vehicle: Vehicle) -> None:
        b = vehicle.body
        self.df = df
        self.vehicle = vehicle
        self.R = R = b.wheel_radius
        t = _f(df, ch.T)
        self.t = t
        idx = np.floor((t - t[0]) / BIN_S).astype(np.int64)
        cnt = np.bincount(idx).astype(np.float64)
        self._idx, self._cnt = idx, cnt
        self.good = cnt >= 0.5 * float(np.median(cnt[cnt > 0])) if len(t) > 1 else cnt > 0
        self.r = self.bin(_f(df, "yaw_rate"))
        self.ay = self.bin(_f(df, "ay"))
        delta = road_wheel_angles(df, b.steering_ratio).mean(axis=1)
        self.delta = self.bin(delta)
        self.tb = self.bin(t)
        self.has_wheels = set(ch.WHEEL_SPEEDS) <= set(df.columns)
        self.omega = ({c: self.bin(_f(df, f"omega_{c}")) for c in CORNERS}
                      if self.has_wheels else {})
        if self.has_wheels:
            w4 = np.column_stack([self.omega[c] for c in CORNERS])
            med = np.median(w4, axis=1)
            self.speed_name, self.dspeed_name = "R·ω", "R·Δω"
            with np.errstate(invalid="ignore", divide="ignore"):
                self.v = R * med
                spread = (w4.max(axis=1) - w4.min(axis=1)) / np.abs(med)
                track = max(b.track_f, b.track_r)
                allowed = SPREAD_BASE + 1.3 * track * np.abs(self.r) / np.maximum(self.v, 1e-9)
            self.clean = self.good & (self.v > 0) & (spread <= allowed)
            # Both axles; the front difference is r·track_f·cos δ, and cos δ ≥ 0.98 above
            # V_MIN_YAW, so δ (which may itself be wrong) is left out.
            self.yaw_y = R * ((self.omega["fr"] - self.omega["fl"])
                              + (self.omega["rr"] - self.omega["rl"])) / (b.track_f + b.track_r)
        else:
            name = next((c for c in ch.SPEED_SOURCES if c in df.columns), None)
            speed = np.full(len(t), np.nan)
            if name is not None:
                raw = _f(df, name)
                fin = np.isfinite(raw)
                if int(np.count_nonzero(fin)) >= 2:
                    speed = np.interp(t, t[fin], raw[fin])
            self.speed_name = name or "speed"
            self.dspeed_name = f"Δ{self.speed_name}"
            self.v = self.bin(speed)
            with np.errstate(invalid="ignore"):
                self.clean = self.good & (self.v > 0)
            self.yaw_y = np.full(len(cnt), np.nan)
        self.lat_x = self.v * self.r
        self.lat_sel = self.clean & (self.v >= V_MIN) & (np.abs(self.lat_x) >= AY_MIN)
        self.steady_sel = self.lat_sel & self._steady(_f(df, "yaw_rate"))
        self.yaw_sel = (self.clean & (self.v >= V_MIN_YAW) & (np.abs(self.r) >= YAW_MIN)
                        & (np.abs(self.lat_x) <= AY_MAX_YAW) & np.isfinite(self.yaw_y))
        self.steer_x = self.v * self.delta / b.wheelbase
        self.steer_sel = self.clean & (self.v >= V_MIN) & (np.abs(self.steer_x) >= STEER_MIN)

    def _steady(self, r: np.ndarray) -> np.ndarray:
        """Bins where r stays within STEADY_YAW·|r| over the bin and its two neighbours
        (1.5 s): the range of r's 0.1 s means (gyro noise averaged out), not of the bin
        means, which a 1 Hz steer aliases."""
        n = len(self._cnt)
        dt = float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0
        if dt > 0.0 and np.isfinite(dt):
            r = uniform_filter1d(r, max(1, round(0.1 / dt)), mode="nearest")
        lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
        fin = np.isfinite(r)
        np.minimum.at(lo, self._idx[fin], r[fin])
        np.maximum.at(hi, self._idx[fin], r[fin])
        pad_lo = np.concatenate(([np.inf], lo, [np.inf]))
        pad_hi = np.concatenate(([-np.inf], hi, [-np.inf]))
        wlo = np.minimum(np.minimum(pad_lo[:-2], pad_lo[1:-1]), pad_lo[2:])
        whi = np.maximum(np.maximum(pad_hi[:-2], pad_hi[1:-1]), pad_hi[2:])
        with np.errstate(invalid="ignore"):
            return np.asarray((whi - wlo) <= STEADY_YAW * np.abs(self.r))

    def bin(self, x: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.bincount(self._idx, weights=x, minlength=len(self._cnt)) / self._cnt

    def window_pairs(self, window: float = WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs (k, k + window/BIN_S) of clean bins one window apart."""
        step = round(window / BIN_S)
        k = np.arange(len(self.clean) - step)
        ok = self.clean[k] & self.clean[k + step]
        k = k[ok]
        return k, k + step

    def integral_at_bins(self, x: np.ndarray) -> np.ndarray:
        """∫x dt evaluated at the bin mean times."""
        t = self.t
        cum = np.concatenate(([0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))))
        tb = np.where(np.isfinite(self.tb), self.tb, t[0])
        return np.interp(tb, t, cum)


@dataclass(frozen=True)
class _Ratio:
    value: float      # median ratio y/x over the selected bins
    n: int            # number of bins
    agree: float      # share of bins whose ratio has the sign of the median


def _ratio_check(x: np.ndarray, y: np.ndarray, sel: np.ndarray) -> _Ratio | None:
    n = int(np.count_nonzero(sel))
    if n < MIN_BINS:
        return None
    r = y[sel] / x[sel]
    m = float(np.median(r))
    agree = float(np.mean(np.sign(r) == np.sign(m)))
    return _Ratio(m, n, agree)


def _negative(q: _Ratio | None) -> bool:
    return q is not None and q.value <= -SIGN_RATIO and q.agree >= MAJORITY


def _positive(q: _Ratio | None) -> bool:
    return q is not None and q.value >= SIGN_RATIO and q.agree >= MAJORITY


def _fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares y = s·x + c; returns (s, standard error of s)."""
    if len(x) < 3:
        return math.nan, math.inf
    xm = x - x.mean()
    sxx = float(xm @ xm)
    if sxx <= 0.0:
        return math.nan, math.inf
    s = float(xm @ (y - y.mean())) / sxx
    resid = y - y.mean() - s * xm
    return s, math.sqrt(float(resid @ resid) / max(len(x) - 2, 1) / sxx)


def _robust_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """:func:`_fit`, then one refit without points beyond 4 robust sigmas of the residual."""
    s, _ = _fit(x, y)
    if not math.isfinite(s):
        return math.nan, math.inf
    resid = y - s * x
    resid = resid - np.median(resid)
    mad = 1.4826 * float(np.median(np.abs(resid)))
    keep = np.abs(resid) <= max(4.0 * mad, 1e-12)
    if int(np.count_nonzero(keep)) < MIN_BINS:
        return math.nan, math.inf
    return _fit(x[keep], y[keep])


def _err(channel: str, message: str, evidence: float, check: str) -> Finding:
    return Finding(channel, "error", message, float(evidence), check)


def _warn(channel: str, message: str, evidence: float, check: str) -> Finding:
    return Finding(channel, "warning", message, float(evidence), check)


# --- the checks ------------------------------------------------------------------------------


def _gravity(s: _Signals) -> list[Finding]:
    if "az" not in s.df.columns:
        return []
    m = float(np.median(_f(s.df, "az")))
    if abs(m - G) <= AZ_TOL:
        return []
    if abs(m) < AZ_NO_GRAVITY:
        return [_err("az", f"column 'az' has median {m:.3g} m/s², but az reads +{G} at rest "
                     "(specific force, spec): gravity appears to have been subtracted; add "
                     f"{G} to az", m, "gravity")]
    if abs(m + G) <= AZ_TOL:
        return [_err("az", f"column 'az' has median {m:.4g} m/s², but az reads +{G} at rest: "
                     "the z axis points down (spec: z up); negate az", m, "gravity")]
    if 0.5 <= abs(m) <= 1.5:
        return [_err("az", f"column 'az' has median {m:.4g}: this looks like g units; multiply "
                     f"by {G} to get m/s²", m, "gravity")]
    return [_warn("az", f"column 'az' has median {m:.4g} m/s², far from the +{G} it reads "
                  "when driving on a level road; check its unit, offset and sign", m,
                  "gravity")]


def _wheels_each_other(s: _Signals, out: list[Finding]) -> bool:
    """Each wheel speed against the other three; returns whether the check was evaluated."""
    sel = s.good & (s.v >= V_MIN_YAW)
    if not s.has_wheels or int(np.count_nonzero(sel)) < MIN_BINS:
        return False
    w4 = np.column_stack([s.omega[c] for c in CORNERS])[sel]
    for i, c in enumerate(CORNERS):
        lr = _log_ratio(w4[:, i], np.median(np.delete(w4, i, axis=1), axis=1))
        if len(lr) < MIN_BINS:
            continue
        q25, med, q75 = np.quantile(lr, [0.25, 0.5, 0.75])
        if q75 - q25 > WHEEL_SPREAD or abs(med) < math.log(WHEEL_ALONE):
            continue
        alone = abs(med) < math.log(WHEEL_RATIO)  # a smaller factor: its axle mate's too
        if alone:
            to_mate = _log_ratio(w4[:, i], w4[:, i ^ 1])
            if not len(to_mate) or abs(float(np.median(to_mate))) < math.log(WHEEL_ALONE):
                continue
        factor = math.exp(float(med))
        units = (f"mph read as rad/s gives 2.237·R = {2.237 * s.R:.3g}, km/h 3.6·R = "
                 f"{3.6 * s.R:.3g}" if alone else "rpm gives 9.55, m/s gives 1/R")
        mate_note = ", its axle mate's included" if alone else ""
        out.append(_err(
            f"omega_{c}", f"column 'omega_{c}' is a constant {factor:.3g} × the other wheel "
            f"speeds{mate_note}: it is in another unit ({units}) or scaled differently; convert it "
            "to rad/s like the others", factor, "wheels"))
    return True


def _log_ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """ln |a / b| where finite (a wheel speed against others, rad/s both)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        lr = np.log(np.abs(a) / np.abs(b))
    return lr[np.isfinite(lr)]


def _longitudinal(s: _Signals, out: list[Finding]) -> float | None:
    """Slope of ∫ax dt on the speed change over 1 s (R·Δω of the least-slip wheel, or of the
    speed channel). Returns it or None."""
    k0, k1 = s.window_pairs()
    if len(k0) < MIN_BINS or "ax" not in s.df.columns:
        return None
    a = s.integral_at_bins(_f(s.df, "ax"))
    dv_ax = a[k1] - a[k0]
    best: float | None = None
    best_se = math.inf
    speeds = ([s.R * s.omega[c] for c in CORNERS] if s.has_wheels else [s.v])
    for v in speeds:
        dw = v[k1] - v[k0]
        sel = np.abs(dw) >= LON_MIN_STEP
        if int(np.count_nonzero(sel)) < MIN_BINS:
            continue
        slope, se = _robust_fit(dw[sel], dv_ax[sel])
        if not (math.isfinite(slope) and se <= LON_MAX_REL_SE * abs(slope)):
            continue  # ABS cycling or spin: the wheel does not follow the car
        if best is None or slope > best:
            best, best_se = slope, se
    if best is None:
        return None
    if best < 0 and best / best_se <= -T_STAT:
        out.append(_err("ax", f"column 'ax' falls while the wheels speed up (∫ax dt = "
                        f"{best:.2f} × {s.dspeed_name} over 1 s windows; expected about +1): the x axis "
                        "points backwards or ax has the wrong sign; negate ax", best,
                        "longitudinal"))
    return best


def _pitch_offset(s: _Signals) -> tuple[float, int] | None:
    """median(ax − R·ω̇) in m/s² over the near-steady 1 s windows, and their number; None
    without wheel speeds or ax, or with fewer than MIN_BINS windows. ``ax`` is taken after
    the vehicle file's ``[calibration.imu]`` scale and mounting (what the estimators use)."""
    if not s.has_wheels or "ax" not in s.df.columns:
        return None
    k0, k1 = s.window_pairs()
    if len(k0) < MIN_BINS:
        return None
    ax = _f(s.df, "ax")
    cal = s.vehicle.calibration
    if cal is not None and cal.groups and {"ay", "az"} <= set(s.df.columns):
        cols = {c: _f(s.df, c) for c in ("ax", "ay", "az")}
        correct_columns(cols, cal, wheel_radius=s.R,
                        steering_ratio=s.vehicle.body.steering_ratio)
        ax = cols["ax"]
    a = s.integral_at_bins(ax)
    dt = s.tb[k1] - s.tb[k0]
    with np.errstate(invalid="ignore", divide="ignore"):
        acc = (s.v[k1] - s.v[k0]) / dt
        off = (a[k1] - a[k0]) / dt - acc
        sel = ((np.minimum(s.v[k0], s.v[k1]) >= V_MIN_YAW)
               & (np.maximum(np.abs(s.lat_x[k0]), np.abs(s.lat_x[k1])) <= PITCH_AY_MAX)
               & (np.abs(acc) <= PITCH_ACC_MAX) & np.isfinite(off))
    n = int(np.count_nonzero(sel))
    if n < MIN_BINS:
        return None
    return float(np.median(off[sel])), n


def _pitch(s: _Signals, out: list[Finding]) -> bool:
    """ax against the wheels' speed change over the whole log: gravity leaking into ax from
    an IMU mounted pitched (a warning, an error beyond PITCH_ERROR). Returns whether the
    check was evaluated."""
    got = _pitch_offset(s)
    if got is None:
        return False
    off, n = got
    if abs(off) < PITCH_WARN:
        return True
    # The sensor's x axis PITCH below the body's x-y plane reads ax = ... − g·sin(PITCH).
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, -off / G))))
    grade = 100.0 * math.tan(math.asin(min(1.0, abs(off) / G)))
    way = "nose-down" if pitch > 0 else "nose-up"
    sev = _err if abs(off) >= PITCH_ERROR else _warn
    road = (f"or the whole log was driven {'up' if off > 0 else 'down'} a {grade:.0f} % "
            "grade" if sev is _warn else
            f"no road holds a {grade:.0f} % grade for a whole log")
    out.append(sev("ax, az", f"columns 'ax', 'az' look pitched: over {n} near-steady 1 s "
                   f"windows ax reads a median {off:+.2f} m/s² away from the wheels' speed "
                   f"change R·ω̇ (clean logs on level roads: within ±0.16; ax includes g·sin of "
                   f"the sensor's pitch): an IMU pitched {abs(pitch):.1f}° {way} "
                   f"(asin({-off:.2f}/{G}) = {pitch:+.1f}°), {road}. If the IMU is "
                   f"mounted pitched, declare it: the channel map's [imu] mounting = "
                   f"{{ pitch_deg = {pitch:.1f} }} (docs/channel-map.md), or [calibration.imu] "
                   f"mount_pitch = {math.radians(pitch):.4f} (rad) in the vehicle file; ax "
                   "and az are then rotated into the body axes", off, "pitch"))
    return True


def _yaw_scale(s: _Signals, lat: _Ratio | None, yaw: _Ratio | None,
               out: list[Finding]) -> bool:
    """yaw_rate in deg/s (an error; returns True) or a wheel-speed difference of the wrong
    size for the track (a warning)."""
    lo, hi = YAW_DEG
    for q, what in ((yaw, "the left–right wheel-speed difference R·(ω_right − ω_left)/track"),
                    (lat, f"ay/v (speed {s.speed_name})")):
        if q is not None and q.agree >= MAJORITY and lo <= q.value <= hi:
            out.append(_err("yaw_rate", f"column 'yaw_rate' looks like deg/s, not rad/s: in "
                            f"turns {what} is {q.value:.4f} × yaw_rate (about 1 in rad/s, "
                            f"π/180 = {math.pi / 180:.4f} in deg/s); multiply yaw_rate by "
                            "π/180", q.value, "yaw_wheels" if q is yaw else "lateral"))
            return True
    if _positive(yaw) and yaw is not None and not YAW_NORMAL[0] <= yaw.value <= YAW_NORMAL[1]:
        out.append(_warn("yaw_rate", "in turns the left–right wheel-speed difference "
                         f"R·(ω_right − ω_left)/track is {yaw.value:.3g} × yaw_rate, expected "
                         "about 1: check the units of yaw_rate and the wheel speeds, and "
                         "track_f, track_r and wheel_radius in the vehicle file", yaw.value,
                         "yaw_wheels"))
    return False


def _unit_band(q: _Ratio | None, band: tuple[float, float]) -> bool:
    return q is not None and band[0] <= abs(q.value) <= band[1] and q.agree >= MAJORITY


def _lateral_scale(s: _Signals, lat: _Ratio | None, steady: _Ratio | None,
                   lon: float | None, out: list[Finding]) -> bool:
    """ax/ay in g, or a speed channel in km/h. ``lat`` is ay/(v·r) over every turning bin,
    ``steady`` over the quasi-steady ones (STEADY_YAW): only they can prove a unit error.
    Returns whether ay was found to be in g."""
    kmh_band = KMH_LAT if not s.has_wheels else (math.inf, math.inf)
    if steady is None and (_unit_band(lat, LAT_G) or _unit_band(lat, kmh_band)):
        assert lat is not None
        out.append(_warn("ay", f"in turns ay is {lat.value:.3g} × v·r (speed {s.speed_name} times "
                         "yaw_rate), expected about 1, but the log has no steady turn to tell "
                         f"a unit error (ay in g, {s.speed_name} in km/h) from transient "
                         "steering, where ay = v̇_y + v·r: check the units of ay and the speed",
                         lat.value, "lateral"))
        lat = None
    elif steady is not None:
        lat = steady
    ay_g = _unit_band(lat, LAT_G)
    ax_g = lon is not None and 0 < lon < (LON_G if s.has_wheels else LON_G_SPEED)
    if ax_g and ay_g:
        assert lat is not None and lon is not None
        out.append(_err("ax, ay", f"columns 'ax' and 'ay' look like g, not m/s²: ∫ax dt is "
                        f"{lon:.3f} × the speed change {s.dspeed_name} and ay is {abs(lat.value):.3f} "
                        f"× v·r (both about 1 in m/s², 1/{G} = {1 / G:.3f} in g); multiply ax "
                        f"and ay by {G}", lon, "longitudinal"))
    elif ax_g:
        assert lon is not None
        ay_note = (" (ay agrees with v·r, so it is in m/s²)" if lat is not None else
                   " (the log has too little turning to check ay: if it comes from the same "
                   "sensor, multiply it too)")
        out.append(_err("ax", f"column 'ax' looks like g, not m/s²: over 1 s windows ∫ax dt is "
                        f"{lon:.3f} × the speed change {s.dspeed_name} (about 1 in m/s², "
                        f"{1 / G:.3f} in g); multiply ax by {G}{ay_note}", lon,
                        "longitudinal"))
    elif ay_g:
        assert lat is not None
        ax_note = (" (ax agrees with the wheel speeds, so it is in m/s²)" if lon is not None else
                   " (the log has too little acceleration to check ax: if it comes from the "
                   "same sensor, multiply it too)")
        out.append(_err("ay", f"column 'ay' looks like g, not m/s²: in turns ay is "
                        f"{abs(lat.value):.3f} × v·r (speed {s.speed_name} times yaw_rate; about 1 in "
                        f"m/s², {1 / G:.3f} in g); multiply ay by {G}{ax_note}", lat.value,
                        "lateral"))
    elif _unit_band(lat, kmh_band):
        assert lat is not None
        name = s.speed_name
        out.append(_err(name, f"column '{name}' looks like km/h, not m/s: in turns ay is "
                        f"{abs(lat.value):.3f} × v·r (speed {name} times yaw_rate; about 1 in "
                        f"m/s, 1/3.6 = 0.278 in km/h); divide {name} by 3.6", lat.value,
                        "speed"))
    elif lat is not None and lat.agree >= MAJORITY and not (
            LAT_NORMAL[0] <= abs(lat.value) <= LAT_NORMAL[1]):
        out.append(_warn("ay", f"in turns ay is {lat.value:.3g} × v·r (speed {s.speed_name} times "
                         "yaw_rate), expected about 1: check the units of ay, yaw_rate and "
                         "the wheel speeds, and wheel_radius", lat.value, "lateral"))
    return ay_g


@dataclass(frozen=True)
class _Roll:
    k: float          # roll gradient, rad per m/s² of ay
    tstat: float      # k / its standard error


def _roll(s: _Signals, ay_in_g: bool, out: list[Finding]) -> _Roll | None:
    """Roll gradient k (rad per m/s²) from ∫p dt against Δay over WINDOW_S and ROLL_WINDOW_S
    windows (a sine steer changes ay within 1 s, a ramp steer needs 2 s); the better
    determined of the two fits is used."""
    if "roll_rate" not in s.df.columns:
        return None
    phi = s.integral_at_bins(_f(s.df, "roll_rate"))
    best: tuple[float, float] | None = None
    for window in (WINDOW_S, ROLL_WINDOW_S):
        k0, k1 = s.window_pairs(window)
        dphi = phi[k1] - phi[k0]
        day = (s.ay[k1] - s.ay[k0]) * (G if ay_in_g else 1.0)
        sel = np.abs(day) >= ROLL_MIN_STEP
        if int(np.count_nonzero(sel)) < MIN_BINS:
            continue
        k, se = _robust_fit(day[sel], dphi[sel])
        if math.isfinite(k) and (best is None or abs(k / se) > abs(best[0] / best[1])):
            best = (k, se)
    if best is None:
        return None
    k, se = best
    if k > ROLL_MAX and k / se >= T_STAT:
        out.append(_err("roll_rate", "column 'roll_rate' looks like deg/s, not rad/s: its "
                        f"integral gives a roll gradient of {k:.3g} rad per m/s² of ay "
                        f"({math.degrees(k) * G:.3g}°/g; road cars roll 1–12°/g); multiply "
                        "roll_rate by π/180", k, "roll"))
    return _Roll(k, k / se)


def _signs(s: _Signals, lat: _Ratio | None, yaw: _Ratio | None, steer: _Ratio | None,
           roll: _Roll | None, out: list[Finding]) -> None:
    """Signs of yaw_rate, ay, the steering and roll_rate, relative to the wheels' labels."""
    steer_cols = _steer_columns(s.df)
    roll_neg = roll is not None and roll.tstat <= -T_STAT
    ay_rel = -1 if _negative(lat) else (1 if _positive(lat) else 0)      # ay vs r
    d_rel = -1 if _negative(steer) else (1 if _positive(steer) else 0)   # δ vs r
    r_sign = -1 if _negative(yaw) else (1 if _positive(yaw) else 0)      # r vs wheels
    wheel_fig = yaw.value if yaw is not None else math.nan
    if r_sign == -1:
        flipped = ["yaw_rate"]
        if ay_rel == 1:
            flipped.append("ay")
        if d_rel == 1:
            flipped.append(steer_cols)
        if "ay" in flipped and roll is not None and roll.tstat >= T_STAT:
            flipped.append("roll_rate")  # rolls with ay, so it is mirrored too
        if "ay" in flipped:
            unchecked = [c for c, ok in (("roll_rate", roll is None), (steer_cols, d_rel == 0))
                         if ok and (c != "roll_rate" or "roll_rate" in s.df.columns)]
            note = (f"; {' and '.join(unchecked)} could not be checked (too little excitation): "
                    "negate them too if they come from the same frame" if unchecked else "")
            out.append(_err(
                ", ".join(flipped),
                f"columns {', '.join(flipped)} have the signs of a y axis pointing right: in "
                f"turns the yaw rate is opposite to the left–right wheel-speed difference "
                f"(R·(ω_right − ω_left)/track = {wheel_fig:.2f} × yaw_rate, expected +1) while "
                "ay agrees with yaw_rate. The spec's y axis points left (ISO 8855; yaw, roll and "
                f"steering positive to the left): negate {', '.join(flipped)} (or, if only the "
                f"wheel columns are wrong, swap omega_*l with omega_*r){note}", wheel_fig,
                "yaw_wheels"))
            return
        extra = (" and ay agrees with the wheels (ay = "
                 f"{lat.value:.2f} × v·r)") if ay_rel == -1 and lat is not None else ""
        out.append(_err("yaw_rate", "column 'yaw_rate' has the wrong sign: in turns it is "
                        "opposite to the left–right wheel-speed difference (R·(ω_right − "
                        f"ω_left)/track = {wheel_fig:.2f} × yaw_rate, expected +1){extra}; "
                        "negate yaw_rate (spec: positive turning left)", wheel_fig,
                        "yaw_wheels"))
        if d_rel == 1:
            out.append(_err(steer_cols, f"{steer_cols} has the wrong sign (it agrees with the "
                            "flipped yaw_rate, so it steers right when the car turns left); "
                            "negate it (spec: positive steers left)", steer.value if steer
                            else math.nan, "steering"))
        return
    if ay_rel == -1 and lat is not None:
        if r_sign == 1 or d_rel == 1:
            out.append(_err("ay", f"column 'ay' has the wrong sign: in turns ay = "
                            f"{lat.value:.2f} × v·r (expected about +1) while yaw_rate agrees "
                            "with the wheel speeds and the steering; negate ay (spec: y axis "
                            "left, ay > 0 in a left turn)", lat.value, "lateral"))
        elif d_rel == -1:
            out.append(_err("yaw_rate", "column 'yaw_rate' has the wrong sign: it is opposite "
                            f"to both ay (ay = {lat.value:.2f} × v·r) and the steering angle; "
                            "negate yaw_rate (spec: positive turning left)", lat.value,
                            "lateral"))
        else:
            out.append(_err("ay, yaw_rate", "columns 'ay' and 'yaw_rate' have opposite signs "
                            f"(in turns ay = {lat.value:.2f} × v·r, expected about +1): one of "
                            "them is negated, or the y axis points right; the log has too "
                            "little turning with clean wheel speeds to tell which. Spec: y "
                            "left, ay > 0 and yaw_rate > 0 in a left turn", lat.value,
                            "lateral"))
        return
    if d_rel == -1 and steer is not None and r_sign == 0 and ay_rel == 0:
        out.append(_err(f"{steer_cols}, yaw_rate", f"{steer_cols} and yaw_rate have opposite "
                        f"signs (the car yaws against the steering: yaw_rate = "
                        f"{steer.value:.2f} × v·δ/L, expected +0.3 to +1.3): one of them is "
                        "negated; the log has too little turning with clean wheel speeds to "
                        "tell which. Spec: both positive to the left", steer.value, "steering"))
    elif d_rel == -1 and steer is not None:
        out.append(_err(steer_cols, f"{steer_cols} has the wrong sign: the car yaws opposite to "
                        f"the steering (yaw_rate = {steer.value:.2f} × v·δ/L, expected +0.3 to "
                        "+1.3) while yaw_rate agrees with ay and the wheel speeds; negate it "
                        "(spec: positive steers left)", steer.value, "steering"))
    if roll_neg and roll is not None:
        out.append(_err("roll_rate", "column 'roll_rate' has the wrong sign: the body rolls "
                        "into the turn (∫roll_rate dt falls as ay rises, slope/standard error "
                        f"= {roll.tstat:.1f}); negate roll_rate (spec: positive when the left side "
                        "rises, as it does in a left turn)", roll.k, "roll"))


def _steer_columns(df: pd.DataFrame) -> str:
    if set(ch.ROAD_WHEEL_ANGLES) <= set(df.columns):
        return ", ".join(ch.ROAD_WHEEL_ANGLES)
    if ch.DELTA in df.columns:
        return ch.DELTA
    return ch.STEERING_WHEEL_ANGLE


def _steering_scale(s: _Signals, steer: _Ratio | None, out: list[Finding]) -> None:
    if steer is None or steer.agree < MAJORITY or steer.value <= 0:
        return
    cols = _steer_columns(s.df)
    ratio_note = (f" or [vehicle] steering_ratio = {s.vehicle.body.steering_ratio} is wrong"
                  if cols == ch.STEERING_WHEEL_ANGLE else
                  " or it holds the steering-wheel angle (put that in steering_wheel_angle)")
    v = steer.value
    if v < STEER_LOW[1]:
        sev = _err if v < STEER_LOW[0] else _warn
        out.append(sev(cols, f"{cols} is too large for the yaw rate: in turns yaw_rate = "
                       f"{v:.3g} × v·δ/L (kinematic steering gives 0.3–1.3): δ looks like "
                       f"degrees (convert with ×π/180){ratio_note}", v, "steering"))
    elif v > STEER_HIGH[0]:
        sev = _err if v > STEER_HIGH[1] else _warn
        note = (f" or [vehicle] steering_ratio = {s.vehicle.body.steering_ratio} is too large"
                if cols == ch.STEERING_WHEEL_ANGLE else
                " (divided by the steering ratio twice?)")
        out.append(sev(cols, f"{cols} is too small for the yaw rate: in turns yaw_rate = "
                       f"{v:.3g} × v·δ/L (kinematic steering gives 0.3–1.3): check its unit "
                       f"and scale{note}", v, "steering"))


def _torque(s: _Signals, out: list[Finding]) -> bool:
    """The wheel torques' signs; returns whether the check was evaluated."""
    if not set(ch.TORQUES) <= set(s.df.columns):
        return False
    k0, k1 = s.window_pairs()
    dt = s.tb[k1] - s.tb[k0]
    dw = s.v[k1] - s.v[k0]
    sel = np.abs(dw) >= TORQUE_MIN_STEP
    if int(np.count_nonzero(sel)) < MIN_BINS:
        return False
    m = s.vehicle.body.mass
    x = (m * s.R * dw / dt)[sel]   # N·m the car's acceleration needs at the wheels
    mean_t = {}
    for c in CORNERS:
        tq = s.integral_at_bins(_f(s.df, f"torque_{c}"))
        mean_t[c] = ((tq[k1] - tq[k0]) / dt)[sel]
    total, se = _robust_fit(x, sum(mean_t.values()))
    if math.isfinite(total) and total < 0 and total / se <= -T_STAT:
        out.append(_err(", ".join(ch.TORQUES),
                        f"the wheel torques have the wrong sign: their sum is {total:.2f} × "
                        "m·R·a (the torque the car's acceleration needs, expected about +1): "
                        "negative torques accelerate the car; negate torque_fl, torque_fr, torque_rl and "
                        "torque_rr "
                        "(spec: net wheel torque, drive minus brake, positive driving)", total,
                        "torque"))
        return True
    if math.isfinite(total) and total > 0 and total / se >= T_STAT and not (
            1 / TORQUE_SCALE <= total <= TORQUE_SCALE):
        hint = ("kN·m read as N·m gives 0.001: multiply them by 1000" if total < 1
                else "N·m declared as kN·m (or read in N·mm) gives 1000: divide them by 1000")
        out.append(_err(", ".join(ch.TORQUES),
                        f"the wheel torques {', '.join(ch.TORQUES)} are {total:.4g} × m·R·a "
                        "(the torque the car's "
                        "acceleration needs at the wheels; expected about 1, clean logs "
                        f"0.97–1.20): they are in another unit ({hint}), or check mass and "
                        "wheel_radius in the vehicle file", total, "torque"))
        return True
    for c in CORNERS:
        k, se_c = _robust_fit(x, mean_t[c])
        if math.isfinite(k) and k < 0 and k / se_c <= -T_STAT:
            out.append(_err(f"torque_{c}", f"column 'torque_{c}' has the wrong sign: it is "
                            f"{k:.2f} × m·R·a (each wheel's share is ≥ 0) while the sum of "
                            "the torques agrees with the car's acceleration; negate it", k,
                            "torque"))
    return True


def _wheel_scale(s: _Signals, lat: _Ratio | None, yaw: _Ratio | None, roll: _Roll | None,
                 ay_in_g: bool, lon: float | None, out: list[Finding]) -> None:
    """Wheel speeds in km/h (scale 3.6·R) that validate_log cannot tell from rad/s, and a
    speed channel (gnss_speed, vehicle_speed) in km/h or disagreeing with the wheels."""
    if not s.has_wheels:
        return
    c = 3.6 * s.R
    lnc = math.log(c)
    checkable = abs(lnc) >= KMH_MIN

    def supports(estimate: float) -> bool:
        return checkable and SCALE_EVIDENCE <= math.log(estimate) / lnc <= 1 / SCALE_EVIDENCE

    fix = f"convert with ×1/(3.6·R) = ×{1 / c:.4g}, or check wheel_radius = {s.R} m"
    referenced = False
    for name in (ch.GNSS_SPEED, ch.VEHICLE_SPEED):
        if name not in s.df.columns:
            continue
        raw = _f(s.df, name)
        fin = np.isfinite(raw)
        if int(np.count_nonzero(fin)) < 2:
            continue
        ref = s.bin(np.interp(s.t, s.t[fin], raw[fin]))  # gnss_speed: between its fixes
        with np.errstate(invalid="ignore"):
            sel = s.clean & (ref >= V_MIN)  # bins without a spinning or locked wheel
        if int(np.count_nonzero(sel)) < MIN_BINS:
            continue
        referenced = True
        rho = float(np.median(s.v[sel] / ref[sel]))
        if abs(math.log(rho * 3.6)) <= KMH_SPEED_TOL:
            out.append(_err(name, f"column '{name}' looks like km/h, not m/s: R·ω is "
                            f"{rho:.3f} × {name} (1 in m/s, 1/3.6 = 0.278 in km/h); divide "
                            f"{name} by 3.6", rho, "speed"))
        elif supports(rho):
            out.append(_err(OMEGAS, f"columns {OMEGAS} look like km/h, not rad/s: R·ω is "
                            f"{rho:.3f} × {name} (rad/s gives 1, km/h gives 3.6·R = {c:.3f}); "
                            f"{fix}", rho, "speed"))
        elif abs(math.log(rho)) > GNSS_TOL:
            out.append(_warn(f"{OMEGAS}, {name}", f"R·ω is {rho:.3f} × {name} (expected 1 "
                             f"within 8 %): check wheel_radius = {s.R} m and the units of "
                             f"{OMEGAS} and {name}", rho, "speed"))
    if referenced or not checkable:
        return
    # Without a speed channel: the lateral relation (corrected for roll) and the yaw relation
    # each estimate the wheel-speed scale; only both together count, as a warning.
    if lat is None or yaw is None or roll is None or roll.k <= 0 or ay_in_g:
        return
    if not (_positive(lat) and _positive(yaw)):
        return
    rho_lat = 1.0 / (lat.value * (1.0 - G * roll.k))
    rho_yaw = yaw.value
    if rho_lat > 0 and supports(rho_lat) and supports(rho_yaw):
        lon_note = f"; ∫ax dt is {lon:.3f} × R·Δω" if lon is not None else ""
        out.append(_warn(OMEGAS,
                         f"columns {OMEGAS} may be in km/h, not rad/s: they make the car "
                         f"{rho_lat:.3f} × too fast for ay/yaw_rate (roll-corrected) and "
                         f"{rho_yaw:.3f} × too fast for yaw_rate across the track{lon_note} "
                         f"(rad/s gives 1, km/h 3.6·R = {c:.3f}); {fix}",
                         math.sqrt(rho_lat * rho_yaw), "lateral"))
