"""The ``[calibration]`` tables of a calibrated vehicle file (``vestim calibrate``, issue 13).

``vestim calibrate LOG… --vehicle BASE.toml --out CAR.toml`` writes the base file's tables
unchanged and adds what it identified from the logs, one table per group::

    [calibration]
    base = "vehicle2.toml"             # the file calibrated
    sources = ["x05.parquet", ...]     # the logs it was calibrated from
    vestim_version = "0.1.0"

    [calibration.wheels]
    radius_fl = 0.3512                 # the value (SI unit of the key, below)
    sigma_radius_fl = 0.0004           # its one-σ uncertainty
    excited_radius_fl = true           # false: the logs did not determine it
    evidence_radius_fl = "x05: 41 s of straight free rolling at 8-27 m/s"
    used_radius_fl = true              # false: the nominal value stays (decision_<key>)
    decision_radius_fl = "used: 22σ from nominal 0.35 m; held-out χ² 1.05 against ..."

A value the logs did not excite keeps the base value, with ``excited_<key> = false``,
``sigma_<key> = nan`` and the reason as its evidence. An excited value is used only when it
passed ``vestim calibrate``'s selection (:mod:`vestim.design.calibrate.select`: more than
k·σ from the nominal value and better than it on the held-out logs); otherwise
``used_<key> = false`` and ``decision_<key>`` says why the nominal value stays. A file
without ``used_<key>`` (written before the selection) uses every excited value. The keys of
each group and their units are :data:`KEYS`. How the estimators use them
(:func:`corrected_log` and the stages):

- ``wheels``: each wheel's effective rolling radius; ``omega_<c>`` is scaled by
  radius_<c> / ``[vehicle] wheel_radius`` before estimation. ``radius_scale`` (their mean
  over the file's radius) and ``gnss_latency`` (s, the GNSS receiver's latency found with
  it) are reported.
- ``imu``: biases (sensor axes; reported, not applied: a turn-on bias changes from drive
  to drive, and the estimators find each log's online), ``accel_scale`` (the
  accelerometer's |g| reading / g; the specific force is divided by it) and the mounting rotation
  ``mount_roll``, ``mount_pitch``, ``mount_yaw`` (rad; the convention of
  :func:`vestim.io.channel_map.mounting_matrix`) that takes sensor axes to body axes.
- ``steering``: ``steering_offset`` (rad of road-wheel angle, subtracted) and
  ``steering_ratio`` (the car's steering-wheel/road-wheel ratio; road-wheel angles derived
  from the steering-wheel angle with ``[vehicle] steering_ratio`` are rescaled to it);
  ``understeer_gradient`` (rad per m/s²) is reported only.
- ``body``: ``roll_gradient`` = dφ/da_y and ``pitch_gradient`` = −dθ/da_x (rad per m/s²,
  both positive on a car: it rolls out of a turn and its nose rises when accelerating): the
  attitude filter's quasi-static roll and pitch (``vestim.estimators.force.normal``), as a
  stated ``[suspension]`` would give them.
- ``tire``: axle cornering stiffness ``cy_f``, ``cy_r`` (N/rad) — the prior of the online
  cornering-stiffness regression — and longitudinal slip stiffness ``cx_f``, ``cx_r`` (N per
  unit slip) — the friction stage's K_x; LuGre parameters identified from the logs are
  written into ``[tire]`` itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from vestim.errors import VehicleFileError

KEYS: dict[str, dict[str, str]] = {
    "wheels": {**{f"radius_{c}": "m" for c in ("fl", "fr", "rl", "rr")},
               "radius_scale": "-", "gnss_latency": "s"},
    "imu": {"bias_ax": "m/s^2", "bias_ay": "m/s^2", "bias_az": "m/s^2",
            "bias_yaw_rate": "rad/s", "bias_roll_rate": "rad/s", "bias_pitch_rate": "rad/s",
            "accel_scale": "-", "mount_roll": "rad", "mount_pitch": "rad", "mount_yaw": "rad"},
    "steering": {"steering_ratio": "-", "steering_offset": "rad",
                 "understeer_gradient": "rad/(m/s^2)"},
    "body": {"roll_gradient": "rad/(m/s^2)", "pitch_gradient": "rad/(m/s^2)"},
    "tire": {"cy_f": "N/rad", "cy_r": "N/rad", "cx_f": "N", "cx_r": "N",
             "sigma0_x": "1/m", "sigma1_x": "s/m", "sigma2_x": "s/m", "kappa_x": "1/m",
             "sigma0_y": "1/m", "sigma1_y": "s/m", "sigma2_y": "s/m", "kappa_y": "1/m",
             "mu_s": "-", "mu_c": "-", "v_s": "m/s", "alpha": "-"},
}
"""Every key ``vestim calibrate`` may write, per group, with its SI unit."""

LUGRE_KEYS = ("sigma0_x", "sigma1_x", "sigma2_x", "kappa_x", "sigma0_y", "sigma1_y",
              "sigma2_y", "kappa_y", "mu_s", "mu_c", "v_s", "alpha")
"""The ``tire`` keys that are also ``[tire]`` keys (written there when excited)."""


@dataclass(frozen=True)
class Identified:
    """A calibrated quantity.

    Attributes:
        value: the identified value (SI unit ``unit``); the base value when not excited.
        sigma: one-σ uncertainty of ``value`` (same unit); NaN when not excited.
        excited: False when the logs do not determine the value ("not excited").
        evidence: the data it was found from, for the report: which logs, how many
            seconds or samples, over which range (e.g. "x05, x08: 41 s of straight free
            rolling at 8-27 m/s"), or why it was not excited.
        unit: the value's unit, e.g. "m", "rad", "m/s^2", "N/rad", "-".
        used: False when the selection kept the nominal value
            (:mod:`vestim.design.calibrate.select`); the estimators then ignore ``value``.
        decision: the selection's reason, for the report ("" before the selection).
    """

    value: float
    sigma: float
    excited: bool
    evidence: str
    unit: str
    used: bool = True
    decision: str = ""

    def __post_init__(self) -> None:
        if not math.isfinite(self.value):
            raise ValueError(f"identified value must be finite, got {self.value}")
        if self.excited and not (math.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"an excited value needs a finite sigma >= 0, got {self.sigma}")

    @classmethod
    def not_excited(cls, base: float, why: str, unit: str) -> Identified:
        """The base value kept, with the reason the logs did not determine it."""
        return cls(float(base), math.nan, False, why, unit)


@dataclass(frozen=True)
class Calibration:
    """The ``[calibration]`` tables: identified values per group (see :data:`KEYS`)."""

    groups: Mapping[str, Mapping[str, Identified]] = field(default_factory=dict)
    base: str = ""
    sources: tuple[str, ...] = ()
    vestim_version: str = ""

    def get(self, group: str, key: str) -> Identified | None:
        """The value of ``[calibration.<group>] <key>``, or None when the file has none."""
        return self.groups.get(group, {}).get(key)

    def excited(self, group: str, key: str) -> float | None:
        """The value the estimators use: determined by the logs and kept by the selection
        (``used``, :mod:`vestim.design.calibrate.select`); else None (the nominal stays)."""
        v = self.get(group, key)
        return v.value if v is not None and v.excited and v.used else None


def length_unit(value: float, typical: float) -> str:
    """The wrong unit, cm or mm, whose conversion of ``value`` lands nearest ``typical`` m."""
    unit, scale = min((("centimetres", 100.0), ("millimetres", 1000.0)),
                      key=lambda u: abs(math.log(value / u[1] / typical)))
    return f"{unit} ({value:g} {unit[0]}m = {value / scale:g} m)"


MOUNT_MAX = math.radians(30.0)
"""rad; largest mounting angle a calibration may hold: it is the residual misalignment of an
IMU (a few degrees); a sensor mounted sideways, upside down or backwards is turned into body
axes by the channel map's ``[imu] frame`` and ``mounting`` (docs/channel-map.md)."""

RANGES: dict[str, tuple[float, float, str]] = {
    **{f"radius_{c}": (0.1, 2.0, "an effective rolling radius in metres (a car's is "
                       "0.25–0.40 m)") for c in ("fl", "fr", "rl", "rr")},
    "radius_scale": (0.8, 1.25, "the calibrated radii over [vehicle] wheel_radius: a few per "
                     "cent from 1 (load, pressure, wear)"),
    "gnss_latency": (0.0, 2.0, "a GNSS receiver's latency in seconds (typically 0.05–0.3 s)"),
    **{f"bias_{a}": (-2.0, 2.0, "an accelerometer turn-on bias in m/s² (below 0.5 for a "
                     "MEMS sensor); ±9.81 means gravity was added or removed")
       for a in ("ax", "ay", "az")},
    **{f"bias_{r}": (-0.1, 0.1, "a gyro turn-on bias in rad/s (a MEMS gyro's is 0.005–0.01 "
                     "rad/s); a larger value looks like deg/s: convert with ×π/180")
       for r in ("yaw_rate", "roll_rate", "pitch_rate")},
    "accel_scale": (0.8, 1.25, "the accelerometer's |g| reading over g: a few per cent from 1; "
                    "about 0.1 means the IMU reads g, not m/s² (fix that in the channel map)"),
    **{f"mount_{a}": (-MOUNT_MAX, MOUNT_MAX, "a residual IMU misalignment in rad (a few "
                      "degrees); give radians, not degrees, and put a sensor mounted sideways "
                      "or backwards into body axes with the channel map's [imu] frame and "
                      "mounting (docs/channel-map.md)") for a in ("roll", "pitch", "yaw")},
    "steering_ratio": (5.0, 40.0, "a steering-wheel/road-wheel angle ratio (12–20 for a car)"),
    "steering_offset": (-0.1, 0.1, "a road-wheel angle offset in rad (a few tenths of a "
                        "degree); a larger value looks like degrees: convert with ×π/180"),
    "understeer_gradient": (-0.05, 0.05, "rad per m/s² (a car's is 0.001–0.01)"),
    "roll_gradient": (-0.005, 0.06, "rad of roll per m/s² of a_y (road cars 0.002–0.021); "
                      "degrees per g would be about 60 times larger"),
    "pitch_gradient": (-0.01, 0.03, "rad of pitch per m/s² of a_x (road cars 0.001–0.004)"),
    **{k: (1e3, 2e6, "an axle cornering stiffness in N/rad (a car axle's is 5e4–2e5)")
       for k in ("cy_f", "cy_r")},
    **{k: (1e3, 1e7, "an axle longitudinal slip stiffness in N per unit slip")
       for k in ("cx_f", "cx_r")},
    **{k: (1.0, 1e5, "a LuGre bristle stiffness in 1/m (hundreds)") for k in ("sigma0_x",
                                                                          "sigma0_y")},
    **{k: (0.0, 1e3, "a LuGre damping in s/m") for k in ("sigma1_x", "sigma1_y",
                                                        "sigma2_x", "sigma2_y")},
    **{k: (0.0, 1e3, "a LuGre load-distribution factor in 1/m") for k in ("kappa_x",
                                                                          "kappa_y")},
    **{k: (0.0, 3.0, "a normalised friction coefficient (≤ 1.3 on a dry road)")
       for k in ("mu_s", "mu_c")},
    "v_s": (0.0, 100.0, "a Stribeck velocity in m/s"),
    "alpha": (0.0, 5.0, "a Stribeck exponent (0.5–2)"),
}
"""Plausible range (low, high, what the value is) of every :data:`KEYS` value: each is beyond
every road car in SI units, and the usual mistakes (mm for m, degrees for rad, deg/s for
rad/s, g for m/s², a sensor turned by 180°) land outside it."""


def _range_error(where: str, key: str, value: float, unit: str) -> VehicleFileError | None:
    lo, hi, what = RANGES[key]
    if lo <= value <= hi:
        return None
    fix = what
    if key.startswith("radius_") and value > hi:
        fix = f"this looks like {length_unit(value, 0.35)}; give it in metres"
    elif key.startswith("mount_") and abs(value) > math.pi / 2:
        fix = (f"{math.degrees(value):.0f}° is a sensor turned round, not a misalignment; "
               "turn it into body axes with the channel map's [imu] frame and mounting "
               "(docs/channel-map.md) and recalibrate, or give radians, not degrees")
    return VehicleFileError(f"{where} {key} = {value:g} {unit} is outside the plausible range "
                            f"[{lo:g}, {hi:g}] {unit}; {fix}")


SUFFIXED = ("sigma_", "excited_", "evidence_", "used_", "decision_")
"""The prefixes of the keys that describe a value ``<key>`` of a ``[calibration.<group>]``."""


def parse_calibration(table: Any) -> Calibration:
    """Validate a ``[calibration]`` table (parsed TOML); errors name ``[calibration.<g>] key``."""
    if not isinstance(table, dict):
        raise VehicleFileError("[calibration] must be a table")
    top = {"base", "sources", "vestim_version", *KEYS}
    unknown = sorted(set(table) - top)
    if unknown:
        raise VehicleFileError(f"[calibration] unknown key(s) {', '.join(unknown)}; allowed: "
                               f"{', '.join(sorted(top))}")
    sources = table.get("sources", [])
    if not isinstance(sources, list) or not all(isinstance(s, str) for s in sources):
        raise VehicleFileError("[calibration] sources must be a list of file names")
    for key in ("base", "vestim_version"):
        if not isinstance(table.get(key, ""), str):
            raise VehicleFileError(f"[calibration] {key} must be a string")
    groups: dict[str, dict[str, Identified]] = {}
    for group, units in KEYS.items():
        if group not in table:
            continue
        g = table[group]
        where = f"[calibration.{group}]"
        if not isinstance(g, dict):
            raise VehicleFileError(f"{where} must be a table")
        allowed = {f"{p}{k}" for k in units for p in ("", *SUFFIXED)}
        bad = sorted(set(g) - allowed)
        if bad:
            raise VehicleFileError(f"{where} unknown key(s) {', '.join(bad)}; allowed: "
                                   f"{', '.join(units)} and their {', '.join(SUFFIXED)}")
        values: dict[str, Identified] = {}
        for key, unit in units.items():
            if key not in g:
                extra = [f"{p}{key}" for p in SUFFIXED if f"{p}{key}" in g]
                if extra:
                    raise VehicleFileError(f"{where} {extra[0]} without {key}")
                continue
            value, sigma = g[key], g.get(f"sigma_{key}", math.nan)
            excited, evidence = g.get(f"excited_{key}", True), g.get(f"evidence_{key}", "")
            used, decision = g.get(f"used_{key}", True), g.get(f"decision_{key}", "")
            for name, v in ((key, value), (f"sigma_{key}", sigma)):
                if isinstance(v, bool) or not isinstance(v, int | float):
                    raise VehicleFileError(f"{where} {name} = {v!r} must be a number")
            for name, flag in (("excited", excited), ("used", used)):
                if not isinstance(flag, bool):
                    raise VehicleFileError(f"{where} {name}_{key} = {flag!r} must be true or "
                                           "false")
            for name, text in (("evidence", evidence), ("decision", decision)):
                if not isinstance(text, str):
                    raise VehicleFileError(f"{where} {name}_{key} must be a string")
            try:
                problem = _range_error(where, key, float(value), unit)
                if problem is not None:
                    raise problem
                values[key] = Identified(float(value), float(sigma), excited, evidence, unit,
                                         used, decision)
            except (ValueError, OverflowError) as exc:
                if isinstance(exc, VehicleFileError):
                    raise
                raise VehicleFileError(f"{where} {key}: {exc}") from None
        groups[group] = values
    return Calibration(groups, str(table.get("base", "")), tuple(sources),
                       str(table.get("vestim_version", "")))


def toml_value(v: Any) -> str:
    """One TOML value (bool, integer, float with nan and inf, string, list or tuple) as text;
    the writer of every TOML table vestim writes (vehicle files, pipeline configs)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return "nan" if math.isnan(v) else repr(float(v))  # a NumPy float's repr is not TOML
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", " ") + '"'
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {v!r}")


def calibration_toml(cal: Calibration) -> str:
    """The ``[calibration]`` tables as TOML text (round trip: :func:`parse_calibration`)."""
    lines = ["[calibration]", f"base = {toml_value(cal.base)}",
             f"sources = {toml_value(list(cal.sources))}",
             f"vestim_version = {toml_value(cal.vestim_version)}"]
    for group, units in KEYS.items():
        values = cal.groups.get(group)
        if not values:
            continue
        lines += ["", f"[calibration.{group}]"]
        for key in units:
            v = values.get(key)
            if v is None:
                continue
            lines += [f"{key} = {toml_value(v.value)}  # {v.unit}",
                      f"sigma_{key} = {toml_value(v.sigma)}",
                      f"excited_{key} = {toml_value(v.excited)}",
                      f"evidence_{key} = {toml_value(v.evidence)}"]
            if v.excited:
                lines += [f"used_{key} = {toml_value(v.used)}",
                          f"decision_{key} = {toml_value(v.decision)}"]
    return "\n".join(lines) + "\n"


def corrected_log(df: pd.DataFrame, cal: Calibration | None, *, wheel_radius: float,
                  steering_ratio: float) -> pd.DataFrame:
    """The log with the calibrated sensor corrections applied (a new frame; ``df`` unchanged).

    Args:
        df: a drive log (spec columns).
        cal: the vehicle file's calibration (None: ``df`` is returned as it is).
        wheel_radius: the vehicle file's ``[vehicle] wheel_radius``, m.
        steering_ratio: the vehicle file's ``[vehicle] steering_ratio``.

    Returns:
        Wheel speeds scaled to the per-wheel radii, the IMU's biases, scale and mounting
        removed, the steering offset removed and a steering-wheel-derived angle rescaled to
        the identified ratio (see the module docstring). Channels the log lacks stay absent.
    """
    if cal is None or not cal.groups:
        return df
    cols = {c: df[c].to_numpy(dtype=np.float64) for c in CORRECTED if c in df}
    correct_columns(cols, cal, wheel_radius=wheel_radius, steering_ratio=steering_ratio)
    out = df.copy()
    for c, v in cols.items():
        out[c] = v
    return out


CORRECTED = ("omega_fl", "omega_fr", "omega_rl", "omega_rr", "ax", "ay", "az", "roll_rate",
             "pitch_rate", "yaw_rate", "delta_fl", "delta_fr", "delta", "steering_wheel_angle")
"""The channels a calibration corrects."""


def correct_columns(cols: dict[str, np.ndarray], cal: Calibration, *, wheel_radius: float,
                    steering_ratio: float) -> None:
    """:func:`corrected_log` on a mapping of channel arrays (same length), in place: the one
    place the corrections are written, for whole logs and for single samples alike."""
    for c in ("fl", "fr", "rl", "rr"):
        r = cal.excited("wheels", f"radius_{c}")
        if r is not None and f"omega_{c}" in cols:
            cols[f"omega_{c}"] = cols[f"omega_{c}"] * (r / wheel_radius)

    def imu(key: str, default: float) -> float:
        v = cal.excited("imu", key)
        return default if v is None else v

    acc, gyro = ("ax", "ay", "az"), ("roll_rate", "pitch_rate", "yaw_rate")
    # The biases are reported, not applied: an IMU's turn-on bias changes from drive to drive
    # (the crossplant logs each have their own), and the estimators find the accelerometer
    # and yaw-gyro biases of each log online. Applying another drive's bias made the
    # hold-out check worse (docs/results.md, "Calibration hold-out").
    scale = imu("accel_scale", 1.0)
    for name in acc:
        if name in cols:
            cols[name] = cols[name] / scale
    angles = [imu(k, 0.0) for k in ("mount_roll", "mount_pitch", "mount_yaw")]
    if any(a != 0.0 for a in angles):
        from vestim.io.channel_map import mounting_matrix  # io-internal; pint loads lazily

        rot = mounting_matrix(*(math.degrees(a) for a in angles))
        for names in (acc, gyro):
            if all(n in cols for n in names):
                body = np.column_stack([cols[n] for n in names]) @ rot.T
                for j, n in enumerate(names):
                    cols[n] = np.ascontiguousarray(body[:, j])
    offset = cal.excited("steering", "steering_offset") or 0.0
    for name in ("delta_fl", "delta_fr", "delta"):
        if name in cols:
            cols[name] = cols[name] - offset
    ratio = cal.excited("steering", "steering_ratio")
    if ratio is not None and "steering_wheel_angle" in cols and not (
            {"delta", "delta_fl", "delta_fr"} & set(cols)):
        # The road-wheel angle is swa / [vehicle] steering_ratio downstream: scaling swa by
        # file ratio / identified ratio makes it swa / identified ratio.
        cols["steering_wheel_angle"] = cols["steering_wheel_angle"] * (steering_ratio / ratio)
