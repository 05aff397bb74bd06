"""Channel maps: turn a raw, multi-rate recording into a spec drive log.

A channel map is a TOML file (format in ``docs/channel-map.md``) that says, for each spec
channel, which source signal holds it, in which unit, through which arithmetic expression,
and how it is resampled; for the IMU, in which axes and mounting the sensor sits. The
source is read by the reader of its kind (:func:`vestim.io.readers.read_source`), every
signal is put on one time base by time (never by index, so CAN jitter is harmless), units
are converted with pint to the spec's SI units (:func:`vestim.io.channels.unit_of`), the IMU
is rotated into the body frame, and the result is checked with
:func:`vestim.io.log.validate_log`.

Time gaps longer than ``[output] max_gap`` in a dense channel's source are never
interpolated across: by default they are an error naming the channel and the time, and with
``gaps = "trim"`` the longest gap-free span is kept; either way every gap is listed in the
:class:`ImportReport` and in the log's metadata.
"""

from __future__ import annotations

import ast
import json
import math
import operator
import os
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vestim.errors import VestimError
from vestim.io import channels as ch
from vestim.io.log import validate_log
from vestim.io.readers import SOURCE_KINDS, Stream, read_source

__all__ = [
    "ChannelMap",
    "ChannelMapError",
    "ChannelSpec",
    "Gap",
    "ImportReport",
    "Mounting",
    "PoseSpec",
    "evaluate_expression",
    "frame_matrix",
    "import_log",
    "load_channel_map",
    "mounting_matrix",
    "parse_expression",
    "pose_orientation",
    "resample",
    "source_unit",
    "unit_factor",
]

FORMAT_VERSION = 1
RESAMPLE_RULES: tuple[str, ...] = ("linear", "hold", "sparse")
GAP_MODES: tuple[str, ...] = ("error", "trim")
DEFAULT_MAX_GAP = 0.5
"""s; a dense source silent for longer than this is a gap (CAN at 10 ms with jitter never is)."""
MAX_EXPRESSION_LENGTH = 500
"""Characters; a channel expression is a short formula."""
AUTO = "auto"

# --- automatic mounting thresholds --------------------------------------------------------------
AUTO_MIN_SPEED = 5.0
"""m/s; pose samples slower than this do not vote on the direction of travel (their direction
is dominated by noise and crabbing when parking)."""
AUTO_LOWPASS_HZ = 0.5
"""Hz; the accelerometer, gyro and wheel speeds are low-passed (2nd-order Butterworth, zero
phase) before the gravity and dv/dt fits, which removes road and engine vibration."""
AUTO_STEADY_DOMEGA = 0.5
"""rad/s²; "steady" samples change the mean wheel speed by less than this (0.17 m/s² at
R = 0.33 m)."""
AUTO_STRAIGHT_YAW_RATE = 0.02
"""rad/s; "straight" samples yaw slower than this (0.4 m/s² of lateral acceleration at 20 m/s)."""
AUTO_MIN_SAMPLES = 100
"""Minimum number of samples each automatic fit needs."""
AUTO_MOUNT_MAX_DEG = 30.0
"""deg; largest angle an automatic mounting may find (the limit of a calibrated mounting,
:data:`vestim.io.calibration.MOUNT_MAX`): beyond it the map's ``frame`` or an axis sign is
wrong, which a fit would turn into a plausible-looking rotation (issue 30: −54° of yaw)."""


class ChannelMapError(VestimError, ValueError):
    """A channel map is invalid or cannot be applied; the message names the key and the fix."""


# --- units ----------------------------------------------------------------------------------------


@cache
def _ureg() -> Any:
    import pint

    return pint.UnitRegistry()


def _spec_unit(unit: str) -> str:
    """A spec unit string ("m/s²", "N·m", "-") in pint's syntax."""
    if unit == "-":
        return "dimensionless"
    return unit.replace("·", "*").replace("²", "**2")


UNIT_SPELLINGS: dict[str, str] = {
    "Nm": "N*m", "N.m": "N*m", "N m": "N*m", "kNm": "kN*m",
    "U/min": "revolution/minute", "u/min": "revolution/minute", "rev/min": "revolution/minute",
    "rev/s": "revolution/s", "rps": "revolution/s",
    "dps": "deg/s", "°/s": "deg/s", "°": "deg", "deg/sec": "deg/s", "rad/sec": "rad/s",
    "m/s2": "m/s^2", "m/s²": "m/s^2", "m/s/s": "m/s^2", "m/sec2": "m/s^2", "m/sec^2": "m/s^2",
    "kph": "km/h", "kmh": "km/h", "-": "dimensionless", "": "dimensionless",
}
"""Unit spellings of real DBC and MDF4 files that pint does not read as meant, and what they
mean: ``Nm`` (newton metre, not nanometre), ``U/min`` (German Umdrehungen, revolutions per
minute), ``dps`` (degrees per second), ``m/s2`` (m/s²), ``%`` is pint's own percent."""


def _parse_unit(unit: str, column: str) -> Any:
    """``unit`` as a pint Unit (after :data:`UNIT_SPELLINGS`; ``g`` is standard gravity for
    an acceleration), or a ChannelMapError naming the channel."""
    import pint

    ureg = _ureg()
    text = UNIT_SPELLINGS.get(unit.strip(), unit.strip())
    target = ch.unit_of(column)
    if text in ("g", "G") and target is not None and (
            ureg.Unit(_spec_unit(target)).dimensionality == ureg.Unit("m/s**2").dimensionality):
        text = "standard_gravity"
    try:
        return ureg.Unit(text)
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError, ValueError,
            AttributeError, TypeError, SyntaxError, AssertionError) as exc:
        raise ChannelMapError(
            f"channel {column!r}: unknown unit {unit!r} ({exc}); write a pint unit such as "
            "'km/h', 'deg', 'deg/s', 'rpm', 'm/s^2', 'g', 'N*m'"
        ) from None


def ambiguous_rate(unit: str, column: str) -> bool:
    """True when ``unit`` is a bare rate (only time units: ``1/min``, ``1/s``, ``Hz``,
    ``min^-1``) and ``column`` an angular speed (rad/s: omega_*, yaw/roll/pitch_rate).

    Such a unit does not say per minute *of what*: a DBC's ``1/min`` wheel speed counts
    revolutions (×2π to rad), pint would count radians. A unit naming the angle (``rpm``,
    ``U/min``, ``rev/min``, ``rad/s``, ``deg/s``) or a ratio of other units (``km/h / m``,
    a speed over a radius, which is rad/s) is not ambiguous.
    """
    if ch.unit_of(column) != "rad/s":
        return False
    ureg = _ureg()
    parsed = _parse_unit(unit, column)
    names = list(parsed._units)  # pint's UnitsContainer: unit name -> exponent
    time_like = (ureg.get_dimensionality("s"), ureg.get_dimensionality("Hz"))
    # pint's radian is dimensionless, so rpm has the dimension of Hz: look for the angle in
    # each unit's base form.
    return bool(names) and all(
        ureg.get_dimensionality(n) in time_like
        and "radian" not in ureg.Quantity(1.0, n).to_base_units().units._units for n in names)


def unit_factor(unit: str, column: str) -> Callable[[np.ndarray], np.ndarray]:
    """The conversion of values in ``unit`` to the SI unit of spec column ``column``.

    ``unit`` is any pint unit ("km/h", "deg", "deg/s", "rpm", "mm", "ms"…) or a spelling of
    :data:`UNIT_SPELLINGS` (``Nm``, ``U/min``, ``dps``, ``m/s2``, ``%``); ``"g"`` (or
    ``"G"``) means standard gravity for an acceleration, not gram. Offset units (degC) are
    converted with their offset.

    Raises:
        ChannelMapError: unknown unit, a dimension that cannot be converted (e.g. km/h for
            a wheel angular speed), or an ambiguous rate for an angular speed
            (:func:`ambiguous_rate`), naming the channel.
    """
    target = ch.unit_of(column)
    if target is None:
        raise ChannelMapError(f"channel {column!r} is not a spec channel")
    ureg = _ureg()
    tgt = ureg.Unit(_spec_unit(target))
    src = _parse_unit(unit, column)
    if src.dimensionality != tgt.dimensionality:
        raise ChannelMapError(
            f"channel {column!r}: unit {unit!r} ({src.dimensionality}) cannot be converted to "
            f"the spec's {target!r} ({tgt.dimensionality}); give the source's true unit, or an "
            "expression that makes the quantity (e.g. wheel speed in m/s: expr = \"src / "
            "0.35\" with unit = \"rad/s\", the unit of the expression's result)"
        )
    if ambiguous_rate(unit, column):
        raise ChannelMapError(
            f"channel {column!r}: unit {unit!r} is a bare rate: revolutions or radians per "
            "unit of time? (a factor 2π apart); write the angle: unit = \"rpm\" (= \"U/min\", "
            "revolutions per minute) or \"rad/s\""
        )

    def convert(values: np.ndarray) -> np.ndarray:
        return np.asarray(ureg.Quantity(values, src).to(tgt).magnitude, dtype=np.float64)

    return convert


def source_unit(spec: ChannelSpec, streams: Mapping[str, Stream]) -> str:
    """The unit of ``spec``'s values: the map's ``unit``, or the source's where it gives none.

    Without ``expr`` the map's unit must agree with the unit the source carries (a DBC
    signal's or an MDF4 channel's): the same unit in another spelling (``Nm`` and ``N*m``)
    agrees, and so does an angle-bearing unit for a source's bare rate (``rpm`` for
    ``1/min``, which it makes explicit). With ``expr`` the unit is the expression's result's
    and is not compared (the way to override a wrong source label).

    Raises:
        ChannelMapError: no unit in the map nor in the source, or a contradiction; the
            message names the entry, both units and the fix.
    """
    where = f"[channels.{spec.name}]"
    carried = streams["src"].unit if spec.expr is None and "src" in streams else None
    address = spec.sources.get("src", "")
    if spec.unit is None:
        if not carried:
            raise ChannelMapError(
                f"{where}: unit is missing and source {address!r} carries none; give the "
                f"unit of the source, e.g. unit = \"{ch.unit_of(spec.name)}\" if it is already SI"
            )
        if ambiguous_rate(carried, spec.name):
            raise ChannelMapError(
                f"{where}: source {address!r} carries the unit {carried!r}, a bare rate: "
                "revolutions or radians per unit of time? (a factor 2π apart); say which in "
                "the map: unit = \"rpm\" (revolutions per minute) or \"rad/min\""
            )
        return carried
    if not carried:
        return spec.unit
    ureg = _ureg()
    try:
        mine, theirs = _parse_unit(spec.unit, spec.name), _parse_unit(carried, spec.name)
    except ChannelMapError:
        return spec.unit  # a source label pint cannot read: the map says what it means
    ratio = ureg.Quantity(1.0, mine) / ureg.Quantity(1.0, theirs)
    base = ratio.to_base_units()
    agrees = base.dimensionless and abs(float(base.magnitude) - 1.0) < 1e-9
    if not agrees and ambiguous_rate(carried, spec.name):
        agrees = dict(base.units._units) == {"radian": 1}  # rev or rad: the map says which
    if not agrees:
        raise ChannelMapError(
            f"{where}: unit = {spec.unit!r} contradicts the unit {carried!r} that source "
            f"{address!r} carries; remove the map's unit to take the source's, or, if the "
            f"source's label is wrong, write expr = \"src\" with unit = {spec.unit!r} (the "
            "unit of an expression's result is taken as written)"
        )
    return spec.unit


def _time_scale(unit: str, where: str) -> float:
    """Seconds per ``unit`` (a pint time unit)."""
    import pint

    ureg = _ureg()
    try:
        q = ureg.Quantity(1.0, unit).to("s")
    except (pint.errors.UndefinedUnitError, pint.errors.DimensionalityError,
            pint.errors.DefinitionSyntaxError, ValueError, AttributeError, TypeError,
            SyntaxError) as exc:
        raise ChannelMapError(f"{where}: {unit!r} is not a time unit ({exc}); use s, ms, us, ns"
                              ) from None
    return float(q.magnitude)


# --- expressions ------------------------------------------------------------------------------

_BINOPS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.Pow: operator.pow,
}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def parse_expression(text: str, names: frozenset[str] | set[str]) -> ast.Expression:
    """Parse a channel expression and check that it is plain arithmetic.

    Allowed: numbers, the given source ``names``, parentheses, ``+ - * / **`` and unary
    ``+ -``. Anything else (calls, attributes, subscripts, comparisons, other names, strings,
    lambdas…) is refused before anything is evaluated.

    Raises:
        ChannelMapError: a syntax error or a forbidden construct, named.
    """
    if not isinstance(text, str):
        raise ChannelMapError(f"expression {text!r} must be a string")
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ChannelMapError(
            f"expression is {len(text)} characters long; at most {MAX_EXPRESSION_LENGTH}"
        )
    try:
        tree = ast.parse(text.replace("÷", "/").replace("×", "*").replace("^", "**"),
                         mode="eval")
    except SyntaxError as exc:
        raise ChannelMapError(f"expression {text!r} is not valid arithmetic: {exc.msg}") from None
    for node in ast.walk(tree):
        if isinstance(node, ast.Expression | ast.Load):
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            continue
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            continue
        if type(node) in _BINOPS or type(node) in _UNARY:
            continue  # the operator nodes themselves
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            number = node.value
            assert isinstance(number, int | float)
            try:
                float(number)
            except OverflowError:  # an integer literal of more than 308 digits
                digits = len(str(abs(number)))
                raise ChannelMapError(
                    f"expression {text[:60]!r}{'…' if len(text) > 60 else ''}: a number of "
                    f"{digits} digits is beyond the float range (±1.8e308); write it with an "
                    "exponent (e.g. 1e-3) or check the constant") from None
            continue
        if isinstance(node, ast.Name):
            if node.id in names:
                continue
            raise ChannelMapError(
                f"expression {text!r}: unknown name {node.id!r}; the sources it may use are "
                f"{', '.join(sorted(names)) or '(none)'}"
            )
        raise ChannelMapError(
            f"expression {text!r}: {type(node).__name__} is not allowed; write arithmetic "
            "with numbers, source names, + - * / ** and parentheses"
        )
    return tree


def evaluate_expression(text: str, values: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """Evaluate a channel expression (see :func:`parse_expression`) on arrays, in float64.

    Numbers are float64, so ``10 ** 10 ** 10`` gives ``inf`` at once instead of a huge
    integer. The result has the broadcast shape of the inputs.
    """
    tree = parse_expression(text, set(values))
    env = {k: np.asarray(v, dtype=np.float64) for k, v in values.items()}

    def ev(node: ast.AST) -> Any:
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return np.float64(node.value)
        if isinstance(node, ast.Name):
            return env[node.id]
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](ev(node.operand))
        if isinstance(node, ast.BinOp):
            return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
        raise AssertionError(type(node).__name__)  # parse_expression admits nothing else

    with np.errstate(all="ignore"):
        return np.asarray(ev(tree), dtype=np.float64)


# --- frames and mounting ------------------------------------------------------------------------

_AXES: dict[str, tuple[int, float]] = {
    "F": (0, 1.0), "B": (0, -1.0), "L": (1, 1.0), "R": (1, -1.0), "U": (2, 1.0), "D": (2, -1.0),
}


def frame_matrix(frame: str) -> np.ndarray:
    """3×3 matrix taking vectors in sensor axes ``frame`` to the spec's (forward-left-up).

    ``frame`` names the directions of the sensor's x, y and z axes with F/B (forward/back),
    L/R (left/right), U/D (up/down): ``"FLU"`` is the spec's ISO 8855 frame, ``"FRD"``
    forward-right-down (aviation, phones mounted as comma's EON). Left-handed frames are
    refused (a rate about a left-handed axis has no sign convention).
    """
    text = frame.strip().upper() if isinstance(frame, str) else ""
    if len(text) != 3 or any(c not in _AXES for c in text) or len(
            {_AXES[c][0] for c in text}) != 3:
        raise ChannelMapError(
            f"[imu] frame {frame!r}: write three letters, one of F/B, one of L/R and one of U/D "
            "for the sensor's x, y and z axes, e.g. \"FLU\" or \"FRD\""
        )
    m = np.zeros((3, 3))
    for j, c in enumerate(text):
        i, s = _AXES[c]
        m[i, j] = s
    if np.linalg.det(m) < 0:
        raise ChannelMapError(
            f"[imu] frame {frame!r} is left-handed; a gyro's axes are right-handed, so check "
            "the sign of one axis"
        )
    return m


def mounting_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """Rotation taking vectors in the sensor's axes (after the frame conversion) to the body's.

    Convention: the sensor's x axis points ``yaw_deg`` left of the car's forward axis and
    ``pitch_deg`` below the car's x-y plane, i.e. in body axes it is
    ``(cos p cos y, cos p sin y, -sin p)``; the sensor is turned to it from the body by the
    smallest rotation, then rolled by ``roll_deg`` about its own x axis (right side down
    positive). For pure roll, pitch or yaw this is the usual rotation; for pitch and yaw
    together it differs from z-y-x Euler angles by about pitch·yaw/2 of roll (0.027° at 3.8°
    and 0.8°). It is the rotation openpilot-style calibrations find from the direction of
    travel, which sees the sensor's x axis only.
    """
    from scipy.spatial.transform import Rotation

    p, y = math.radians(pitch_deg), math.radians(yaw_deg)
    sx = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p)])
    if sx[0] <= -1.0 + 1e-15:
        raise ChannelMapError("mounting: the sensor's x axis points backwards; use frame")
    # The smallest rotation taking forward to sx is about forward × sx by the angle between them.
    axis = np.cross([1.0, 0.0, 0.0], sx)
    turn = Rotation.from_rotvec(axis / max(float(np.linalg.norm(axis)), 1e-300)
                                * math.atan2(float(np.linalg.norm(axis)), float(sx[0])))
    return np.asarray((turn * Rotation.from_euler("x", roll_deg, degrees=True)).as_matrix())


def _angles_of_travel(d: np.ndarray) -> tuple[float, float]:
    """(pitch_deg, yaw_deg) of the sensor's x axis given the travel direction ``d`` in sensor axes.

    The sensor's x axis in body axes is ``(d_x, -d_y, -d_z)`` (the smallest rotation taking d
    to forward takes forward to that), so yaw = atan2(-d_y, d_x) and pitch = asin(d_z).
    """
    d = d / np.linalg.norm(d)
    return math.degrees(math.asin(float(d[2]))), math.degrees(math.atan2(-float(d[1]),
                                                                          float(d[0])))


# --- the map itself ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ChannelSpec:
    """One spec channel of a map: where it comes from and how it is converted.

    ``sources`` maps expression names to source addresses (one source is named ``src``);
    ``unit`` is the unit of the expression's result (the source's unit without one); None:
    the unit the source carries (a DBC signal's, an MDF4 channel's), see :func:`source_unit`;
    ``offset`` (s) is added to the sources' sample times.
    """

    name: str
    sources: Mapping[str, str]
    unit: str | None
    expr: str | None = None
    resample: str = "linear"
    offset: float = 0.0


@dataclass(frozen=True)
class PoseSpec:
    """An earth-fixed pose of the sensor: velocity (world axes) and orientation quaternion.

    ``orientation`` (w, x, y, z) rotates the pose's ``frame`` axes into the world axes of
    ``velocity`` (``v_world = R(q) v_sensor``). The pose gives ``ref_vx``/``ref_vy`` and the
    direction of travel for ``mounting = "auto"``.
    """

    velocity: tuple[str, str, str]
    orientation: tuple[str, str, str, str]
    velocity_unit: str
    frame: str = "FLU"
    offset: float = 0.0


@dataclass(frozen=True)
class Mounting:
    """The sensor's mounting (see :func:`mounting_matrix`), each angle in degrees.

    ``auto`` lists the angles to be found from the data ("roll", "pitch", "yaw").
    """

    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    yaw_deg: float = 0.0
    auto: tuple[str, ...] = ()


@dataclass(frozen=True)
class ChannelMap:
    """A parsed channel map; see ``docs/channel-map.md`` for every key."""

    channels: Mapping[str, ChannelSpec]
    rate: float
    max_gap: float = DEFAULT_MAX_GAP
    gaps: str = "error"
    kind: str | None = None
    time: str | None = None
    time_unit: str = "s"
    dbc: tuple[Path, ...] = ()
    offset: float = 0.0
    frame: str = "FLU"
    mounting: Mounting = field(default_factory=Mounting)
    travel: str | None = None
    pose: PoseSpec | None = None
    path: Path | None = None
    acceleration: str = "specific_force"


_TOP_KEYS = {"format", "source", "output", "imu", "pose", "channels"}
_SOURCE_KEYS = {"kind", "time", "time_unit", "dbc", "offset"}
_OUTPUT_KEYS = {"rate", "max_gap", "gaps"}
_IMU_KEYS = {"frame", "mounting", "travel", "acceleration"}
_POSE_KEYS = {"velocity", "orientation", "velocity_unit", "frame", "offset"}
_CHANNEL_KEYS = {"source", "sources", "unit", "expr", "resample", "offset"}
_IMU_CHANNELS = ("ax", "ay", "az", "roll_rate", "pitch_rate", "yaw_rate")


def _table(d: Any, where: str, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(d, dict):
        raise ChannelMapError(f"{where} must be a table")
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise ChannelMapError(
            f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}"
        )
    return d


def _number(v: Any, where: str, *, positive: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ChannelMapError(f"{where} = {v!r} must be a finite number")
    if positive and v <= 0:
        raise ChannelMapError(f"{where} = {v!r} must be > 0")
    return float(v)


def _string(v: Any, where: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise ChannelMapError(f"{where} = {v!r} must be a non-empty string")
    return v.strip()


def _columns(v: Any, n: int, where: str) -> tuple[str, ...]:
    """A list of ``n`` addresses, or one base address expanded to ``base[0]`` … (``@`` kept)."""
    if isinstance(v, str):
        base, at, time = v.partition("@")
        return tuple(f"{base}[{i}]{at}{time}" for i in range(n))
    if isinstance(v, list) and len(v) == n:
        return tuple(_string(a, f"{where}[{i}]") for i, a in enumerate(v))
    raise ChannelMapError(f"{where} must be a list of {n} addresses or one base address")


def load_channel_map(path: str | os.PathLike[str]) -> ChannelMap:
    """Read and check a channel map TOML file (format: ``docs/channel-map.md``).

    Raises:
        ChannelMapError: unreadable TOML, unknown or missing keys, wrong types, unknown
            channels, bad units or expressions, each named.
    """
    p = Path(path)
    try:
        with open(p, "rb") as f:
            data = tomllib.load(f)
    except OSError as exc:
        raise ChannelMapError(f"channel map {p}: cannot be read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ChannelMapError(f"channel map {p}: not valid TOML: {exc}") from None
    try:
        return parse_channel_map(data, base=p.parent, path=p)
    except ChannelMapError as exc:
        raise ChannelMapError(f"channel map {p}: {exc}") from None


def parse_channel_map(data: Mapping[str, Any], *, base: Path = Path("."),
                      path: Path | None = None) -> ChannelMap:
    """Check a channel map given as a parsed TOML mapping; see :func:`load_channel_map`."""
    top = _table(dict(data), "the map", _TOP_KEYS)
    fmt = top.get("format", FORMAT_VERSION)
    if fmt != FORMAT_VERSION:
        raise ChannelMapError(f"format = {fmt!r}: this vestim reads format {FORMAT_VERSION}")
    src = _table(top.get("source", {}), "[source]", _SOURCE_KEYS)
    out = _table(top.get("output", {}), "[output]", _OUTPUT_KEYS)
    imu = _table(top.get("imu", {}), "[imu]", _IMU_KEYS)

    kind = src.get("kind")
    if kind is not None and kind not in SOURCE_KINDS:
        raise ChannelMapError(f"[source] kind = {kind!r}: use one of {', '.join(SOURCE_KINDS)}")
    time = _string(src["time"], "[source] time") if "time" in src else None
    time_unit = _string(src.get("time_unit", "s"), "[source] time_unit")
    _time_scale(time_unit, "[source] time_unit")
    dbc_raw = src.get("dbc", [])
    dbc_list = [dbc_raw] if isinstance(dbc_raw, str) else dbc_raw
    if not isinstance(dbc_list, list) or not all(isinstance(x, str) for x in dbc_list):
        raise ChannelMapError("[source] dbc must be a path or a list of paths")
    dbc = tuple(base / x for x in dbc_list)

    if "rate" not in out:
        raise ChannelMapError("[output] rate (Hz, the log's sample rate) is missing")
    rate = _number(out["rate"], "[output] rate", positive=True)
    max_gap = _number(out.get("max_gap", DEFAULT_MAX_GAP), "[output] max_gap", positive=True)
    gaps = out.get("gaps", "error")
    if gaps not in GAP_MODES:
        raise ChannelMapError(f"[output] gaps = {gaps!r}: use one of {', '.join(GAP_MODES)}")

    frame = _string(imu.get("frame", "FLU"), "[imu] frame").upper()
    frame_matrix(frame)
    mounting = _parse_mounting(imu.get("mounting"))
    travel = imu.get("travel")
    if travel is not None and travel not in ("pose", "wheels"):
        raise ChannelMapError(f"[imu] travel = {travel!r}: use \"pose\" or \"wheels\"")
    acceleration = imu.get("acceleration", "specific_force")
    if acceleration not in ("specific_force", "gravity_free"):
        raise ChannelMapError(f"[imu] acceleration = {acceleration!r}: use \"specific_force\" "
                              "(a body-fixed accelerometer) or \"gravity_free\" (an INS's "
                              "levelled accelerations without gravity)")

    pose = None
    if "pose" in top:
        pt = _table(top["pose"], "[pose]", _POSE_KEYS)
        for key in ("velocity", "orientation", "velocity_unit"):
            if key not in pt:
                raise ChannelMapError(f"[pose] {key} is missing")
        pframe = _string(pt.get("frame", "FLU"), "[pose] frame").upper()
        frame_matrix(pframe)
        vunit = _string(pt["velocity_unit"], "[pose] velocity_unit")
        unit_factor(vunit, "ref_vx")
        vel = _columns(pt["velocity"], 3, "[pose] velocity")
        ori = _columns(pt["orientation"], 4, "[pose] orientation")
        pose = PoseSpec(velocity=(vel[0], vel[1], vel[2]),
                        orientation=(ori[0], ori[1], ori[2], ori[3]),
                        velocity_unit=vunit, frame=pframe,
                        offset=_number(pt.get("offset", 0.0), "[pose] offset"))
    if travel == "pose" and pose is None:
        raise ChannelMapError("[imu] travel = \"pose\" needs a [pose] table")

    chans_raw = top.get("channels")
    if not isinstance(chans_raw, dict) or not chans_raw:
        raise ChannelMapError("[channels] is missing or empty; map at least one spec channel")
    channels = {name: _parse_channel(name, spec) for name, spec in chans_raw.items()}
    if pose is not None:
        for name in ("ref_vx", "ref_vy"):
            if name in channels:
                raise ChannelMapError(
                    f"[channels.{name}] and [pose] both give {name}; keep one of them"
                )
    if mounting.auto and not any(c in channels for c in ("ax", "ay", "az")):
        raise ChannelMapError("[imu] mounting \"auto\" needs the accelerometer (ax, ay, az)")
    if mounting.auto and acceleration == "gravity_free":
        raise ChannelMapError("[imu] mounting \"auto\" finds pitch and roll from gravity, "
                              "which gravity_free accelerations do not hold: give the mounting "
                              "angles")
    return ChannelMap(
        channels=channels, rate=rate, max_gap=max_gap, gaps=str(gaps), kind=kind, time=time,
        time_unit=time_unit, dbc=dbc, offset=_number(src.get("offset", 0.0), "[source] offset"),
        frame=frame, mounting=mounting, travel=travel, pose=pose, path=path,
        acceleration=str(acceleration),
    )


def _parse_mounting(v: Any) -> Mounting:
    if v is None:
        return Mounting()
    if v == AUTO:
        return Mounting(auto=("roll", "pitch", "yaw"))
    if not isinstance(v, dict):
        raise ChannelMapError(
            f"[imu] mounting = {v!r}: write \"auto\" or a table {{roll_deg, pitch_deg, yaw_deg}}"
        )
    _table(v, "[imu] mounting", {"roll_deg", "pitch_deg", "yaw_deg"})
    angles: dict[str, float] = {}
    auto: list[str] = []
    for axis in ("roll", "pitch", "yaw"):
        a = v.get(f"{axis}_deg", 0.0)
        if a == AUTO:
            auto.append(axis)
            angles[axis] = 0.0
        else:
            angles[axis] = _number(a, f"[imu] mounting {axis}_deg")
    return Mounting(angles["roll"], angles["pitch"], angles["yaw"], tuple(auto))


def _parse_channel(name: str, spec: Any) -> ChannelSpec:
    where = f"[channels.{name}]"
    if name == ch.T:
        raise ChannelMapError(f"{where}: t is implied by the source clocks; remove it")
    if ch.unit_of(name) is None or (name not in ch.MEASURED and not name.startswith(
            ch.REF_PREFIX)):
        raise ChannelMapError(
            f"{where}: {name!r} is not a measured or reference channel of the log format "
            f"(e.g. {', '.join(ch.MEASURED[1:8])}, …, ref_vx)"
        )
    t = _table(spec, where, _CHANNEL_KEYS)
    if ("source" in t) == ("sources" in t):
        raise ChannelMapError(f"{where}: give exactly one of source = \"ADDRESS\" or "
                              "sources = {name = \"ADDRESS\", …}")
    if "source" in t:
        sources = {"src": _string(t["source"], f"{where} source")}
    else:
        if not isinstance(t["sources"], dict) or not t["sources"]:
            raise ChannelMapError(f"{where} sources must be a table of name = \"ADDRESS\"")
        sources = {}
        for k, a in t["sources"].items():
            if not k.isidentifier():
                raise ChannelMapError(f"{where} sources: {k!r} is not a valid name")
            sources[k] = _string(a, f"{where} sources.{k}")
    expr = t.get("expr")
    if expr is not None:
        try:
            parse_expression(_string(expr, f"{where} expr"), set(sources))
        except ChannelMapError as exc:
            raise ChannelMapError(f"{where} expr: {exc}") from None
    elif len(sources) > 1:
        raise ChannelMapError(f"{where}: several sources need an expr that combines them")
    unit: str | None = None
    if "unit" in t:
        unit = _string(t["unit"], f"{where} unit") if t["unit"] != "-" else "-"
        unit_factor(unit, name)
    elif expr is not None:
        raise ChannelMapError(
            f"{where}: unit is missing; an expression's result has the unit you give it, e.g. "
            f"unit = \"{ch.unit_of(name)}\" if it is already SI"
        )
    rule = t.get("resample", "sparse" if name in ch.SPARSE else "linear")
    if rule not in RESAMPLE_RULES:
        raise ChannelMapError(f"{where} resample = {rule!r}: use one of "
                              f"{', '.join(RESAMPLE_RULES)}")
    if rule == "sparse" and len(sources) > 1:
        raise ChannelMapError(f"{where}: a sparse channel takes one source")
    return ChannelSpec(name=name, sources=sources, unit=unit, expr=expr, resample=rule,
                       offset=_number(t.get("offset", 0.0), f"{where} offset"))


# --- resampling ---------------------------------------------------------------------------------


def resample(stream: Stream, grid: np.ndarray, rule: str, rate: float) -> np.ndarray:
    """Values of ``stream`` on the time ``grid`` (s, spacing 1/``rate``), by time.

    ``linear`` interpolates between the neighbouring samples; ``hold`` takes the latest
    sample at or before each grid time (zero-order hold); ``sparse`` puts each sample on its
    nearest grid row (the nearer one when two fall on the same row) and NaN elsewhere.
    ``linear`` and ``hold`` expect the grid inside the stream's time span.
    """
    t, v = stream.t, stream.value
    if rule == "linear":
        return np.interp(grid, t, v)
    if rule == "hold":
        idx = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 1)
        return v[idx]
    if rule == "sparse":
        out = np.full(len(grid), np.nan)
        pos = (t - grid[0]) * rate
        row = np.rint(pos).astype(np.int64)
        ok = (row >= 0) & (row < len(grid)) & np.isfinite(v)
        err = np.abs(pos - row)
        # Farther samples first, so the nearest one of each row is written last.
        order = np.flatnonzero(ok)[np.argsort(-err[ok], kind="stable")]
        out[row[order]] = v[order]
        return out
    raise ChannelMapError(f"resample rule {rule!r}: use one of {', '.join(RESAMPLE_RULES)}")


@dataclass(frozen=True)
class Gap:
    """A time gap of a source stream longer than ``max_gap``, times in s on the log's clock."""

    channel: str
    address: str
    start: float
    end: float
    sparse: bool = False

    @property
    def length(self) -> float:
        """Gap length, s."""
        return self.end - self.start


@dataclass
class ImportReport:
    """What :func:`import_log` did: clock, gaps, trimming and the IMU mounting used."""

    source: str
    map: str
    rate: float
    t0_source: float
    """s on the source clock of the log's t = 0."""
    gaps: list[Gap] = field(default_factory=list)
    trimmed: tuple[float, float] | None = None
    """(start, end) s of the span kept by ``gaps = "trim"``; None when nothing was cut."""
    mounting: dict[str, Any] | None = None
    """roll/pitch/yaw in degrees and how each was found, when the IMU was rotated."""
    units: dict[str, str] = field(default_factory=dict)
    """channel → the unit its values were read in, with ``" (source)"`` where it was the
    source's own (no ``unit`` in the map, :func:`source_unit`)."""

    def metadata(self) -> dict[str, str]:
        """The report as string metadata for :func:`vestim.io.log.write_log`."""
        meta = {
            "import.source": self.source,
            "import.map": self.map,
            "import.rate_hz": repr(self.rate),
            "import.t0_source_s": repr(self.t0_source),
            "import.gaps": json.dumps([
                {"channel": g.channel, "address": g.address, "start_s": g.start,
                 "end_s": g.end, "sparse": g.sparse} for g in self.gaps]),
        }
        if self.trimmed is not None:
            meta["import.trimmed_s"] = json.dumps(list(self.trimmed))
        if self.mounting is not None:
            meta["import.mounting"] = json.dumps(self.mounting)
        if self.units:
            meta["import.units"] = json.dumps(self.units, ensure_ascii=False)
        return meta


# --- import -------------------------------------------------------------------------------------


def import_log(src: str | os.PathLike[str], map_path: str | os.PathLike[str]
               ) -> tuple[pd.DataFrame, ImportReport]:
    """Read a raw recording through a channel map into a spec drive log.

    Args:
        src: the recording (CSV/Parquet file, numpy folder, MDF4 file, ROS 2 bag), only read.
        map_path: the channel map TOML (``docs/channel-map.md``); relative DBC paths in it
            are taken from its folder.

    Returns:
        ``(log, report)``: the log (``t`` in s from the first common sample, every channel in
        SI units and body axes, validated by :func:`vestim.io.log.validate_log`; the report's
        metadata also in ``log.attrs``) and the :class:`ImportReport`.

    Raises:
        ChannelMapError: an invalid map, or one that does not fit the source (no common time
            span, missing IMU axes for a rotation, too few samples for an automatic mounting,
            a gap longer than ``max_gap`` with ``gaps = "error"``).
        LogFormatError: a reader's error, or a result the log validator refuses.
    """
    cmap = load_channel_map(map_path)
    return apply_channel_map(Path(src), cmap)


def apply_channel_map(src: Path, cmap: ChannelMap) -> tuple[pd.DataFrame, ImportReport]:
    """:func:`import_log` with an already loaded :class:`ChannelMap`."""
    addresses: list[str] = []
    for spec in cmap.channels.values():
        addresses.extend(spec.sources.values())
    if cmap.pose is not None:
        addresses.extend([*cmap.pose.velocity, *cmap.pose.orientation])
    scale = _time_scale(cmap.time_unit, "[source] time_unit")
    raw = read_source(src, list(dict.fromkeys(addresses)), kind=cmap.kind, time=cmap.time,
                      time_scale=scale, dbc=cmap.dbc)

    def shifted(address: str, offset: float) -> Stream:
        s = raw[address]
        if len(s.t) == 0:
            raise ChannelMapError(f"source {address!r} has no samples")
        return Stream(s.t + (cmap.offset + offset), s.value, s.unit)

    per_channel = {name: {k: shifted(a, spec.offset) for k, a in spec.sources.items()}
                   for name, spec in cmap.channels.items()}
    pose_streams = ({a: shifted(a, cmap.pose.offset)
                     for a in (*cmap.pose.velocity, *cmap.pose.orientation)}
                    if cmap.pose is not None else {})

    # Common window of the dense streams: the log covers only times where all have data.
    dense = [(name, spec.sources[k], s) for name, spec in cmap.channels.items()
             if spec.resample != "sparse" for k, s in per_channel[name].items()]
    dense += [("[pose]", a, s) for a, s in pose_streams.items()]
    if not dense:
        raise ChannelMapError("the map has no dense channel (all sparse); nothing sets t")
    t_start = max(float(s.t[0]) for _, _, s in dense)
    t_end = min(float(s.t[-1]) for _, _, s in dense)
    if not t_end > t_start:
        first = max(dense, key=lambda x: float(x[2].t[0]))
        last = min(dense, key=lambda x: float(x[2].t[-1]))
        raise ChannelMapError(
            f"the sources share no time span: {first[0]} ({first[1]!r}) starts at "
            f"{float(first[2].t[0])!r} s but {last[0]} ({last[1]!r}) ends at "
            f"{float(last[2].t[-1])!r} s; check the clock offsets"
        )
    # A last sample within 0.1 % of an interval short of a grid point still counts: clocks
    # stored as float64 seconds since 1970 (ROS 2) resolve only 2.4e-7 s.
    n = math.floor((t_end - t_start) * cmap.rate + 1e-3) + 1
    grid = t_start + np.arange(n) / cmap.rate

    gaps = _find_gaps(cmap, per_channel, pose_streams, t_start, t_end)
    dense_gaps = [g for g in gaps if not g.sparse]
    trimmed = None
    if dense_gaps and cmap.gaps == "error":
        g = dense_gaps[0]
        more = f" (and {len(dense_gaps) - 1} more)" if len(dense_gaps) > 1 else ""
        raise ChannelMapError(
            f"channel {g.channel!r}: source {g.address!r} has no sample for {g.length:.3g} s "
            f"between t = {g.start:.6g} s and t = {g.end:.6g} s of the log (source clock "
            f"{g.start + t_start!r} s){more}, longer than [output] max_gap = "
            f"{cmap.max_gap} s; it is not interpolated across. Set [output] gaps = "
            "\"trim\" to keep the longest gap-free span, or raise max_gap"
        )
    if dense_gaps:  # gaps = "trim": the rest (mounting, pose) sees only the kept span
        keep = _longest_span(grid - t_start, dense_gaps)
        grid = grid[keep]
        trimmed = (float(grid[0] - t_start), float(grid[-1] - t_start))
    data: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    for name, spec in cmap.channels.items():
        unit = source_unit(spec, per_channel[name])
        units[name] = unit if spec.unit is not None else f"{unit} (source)"
        data[name] = _channel_values(spec, unit, per_channel[name], grid, cmap.rate)

    report = ImportReport(source=str(src), map=str(cmap.path or "(in memory)"),
                          rate=cmap.rate, t0_source=t_start, gaps=gaps, trimmed=trimmed,
                          units=units)
    _imu_to_body(cmap, data, grid, pose_streams, report)
    if cmap.pose is not None:
        data.update(_pose_reference(cmap, pose_streams, grid, report))

    df = pd.DataFrame({ch.T: grid - t_start, **data})
    df = df[ch.canonical_order(df.columns)]
    validate_log(df, source=f"{src} (imported through {cmap.path or 'the channel map'})")
    df.attrs.update(report.metadata())
    if cmap.acceleration != "specific_force":  # what the estimators must know of ax, ay, az
        df.attrs["accelerometer"] = cmap.acceleration
    return df, report


def _channel_values(spec: ChannelSpec, unit: str, streams: Mapping[str, Stream],
                    grid: np.ndarray, rate: float) -> np.ndarray:
    """The channel's values on ``grid`` in SI, from ``streams`` in ``unit``."""
    convert = unit_factor(unit, spec.name)
    if spec.resample == "sparse":
        ((key, s),) = streams.items()
        v = s.value if spec.expr is None else evaluate_expression(spec.expr, {key: s.value})
        if spec.expr is not None:
            _check_overflow(spec, {key: s.value}, np.broadcast_to(v, s.value.shape))
        return resample(Stream(s.t, convert(v)), grid, "sparse", rate)
    on_grid = {k: resample(s, grid, spec.resample, rate) for k, s in streams.items()}
    v = on_grid["src"] if spec.expr is None else evaluate_expression(spec.expr, on_grid)
    if spec.expr is not None:
        _check_overflow(spec, on_grid, np.broadcast_to(v, grid.shape))
    return convert(np.broadcast_to(v, grid.shape).copy())


def _check_overflow(spec: ChannelSpec, inputs: Mapping[str, np.ndarray], v: np.ndarray) -> None:
    """A non-finite result of an expression from finite sources is the expression's fault
    (a constant such as 10**400, an overflowing power, a division by zero): name the entry."""
    fin = np.ones(v.shape, dtype=bool)
    for x in inputs.values():
        fin &= np.isfinite(np.broadcast_to(x, v.shape))
    bad = np.flatnonzero(fin & ~np.isfinite(v))
    if bad.size:
        i = int(bad[0])
        args = ", ".join(f"{k} = {float(np.broadcast_to(x, v.shape)[i]):.6g}"
                         for k, x in inputs.items())
        raise ChannelMapError(
            f"[channels.{spec.name}] expr {spec.expr!r} gives {float(v[i])} at sample {i} "
            f"from finite sources ({args}) on {bad.size} of {v.size} samples: an overflow "
            "beyond ±1.8e308 or a division by zero; check its constants and operators")


def _find_gaps(cmap: ChannelMap, per_channel: Mapping[str, Mapping[str, Stream]],
               pose_streams: Mapping[str, Stream], t_start: float, t_end: float) -> list[Gap]:
    """Gaps longer than max_gap inside the log's window, on the log's clock (t = 0 at t_start)."""
    items: list[tuple[str, str, Stream, bool]] = []
    for name, spec in cmap.channels.items():
        for k, s in per_channel[name].items():
            items.append((name, spec.sources[k], s, spec.resample == "sparse"))
    items += [("[pose]", a, s, False) for a, s in pose_streams.items()]
    gaps: list[Gap] = []
    seen: set[tuple[str, float, float]] = set()
    for name, address, s, sparse in items:
        t = s.t
        dt = np.diff(t)
        for i in np.flatnonzero(dt > cmap.max_gap):
            a, b = float(t[i]), float(t[i + 1])
            if b <= t_start or a >= t_end:
                continue
            key = (address, a, b)
            if key in seen:
                continue
            seen.add(key)
            gaps.append(Gap(name, address, max(a, t_start) - t_start, min(b, t_end) - t_start,
                            sparse))
    gaps.sort(key=lambda g: (g.start, g.channel))
    return gaps


def _longest_span(t: np.ndarray, gaps: list[Gap]) -> np.ndarray:
    """Mask of the longest run of grid times ``t`` that no gap touches.

    Rows strictly inside a gap are dropped, and the grid is split between two rows whose
    interval overlaps a gap, so nothing is interpolated across one.
    """
    inside = np.zeros(len(t), dtype=bool)
    split = np.zeros(len(t), dtype=bool)  # split[i]: a gap between rows i-1 and i
    for g in gaps:
        inside |= (t > g.start) & (t < g.end)
        split[1:] |= (t[:-1] < g.end) & (t[1:] > g.start)
    run = np.cumsum(split | inside)
    run[inside] = -1
    ids, counts = np.unique(run[run >= 0], return_counts=True)
    if len(ids) == 0:
        raise ChannelMapError("gaps = \"trim\": no gap-free span is left")
    return np.asarray(run == ids[int(np.argmax(counts))])


# --- IMU frame, mounting, pose ---------------------------------------------------------------


def _imu_to_body(cmap: ChannelMap, data: dict[str, np.ndarray], grid: np.ndarray,
                 pose_streams: Mapping[str, Stream], report: ImportReport) -> None:
    """Rotate the IMU channels (given in the sensor's axes) into the body frame, in place."""
    c = frame_matrix(cmap.frame)
    identity_mount = not cmap.mounting.auto and (
        cmap.mounting.roll_deg == cmap.mounting.pitch_deg == cmap.mounting.yaw_deg == 0.0)
    if identity_mount and np.array_equal(np.abs(c), np.eye(3)):
        for j, (acc, rate) in enumerate((("ax", "roll_rate"), ("ay", "pitch_rate"),
                                          ("az", "yaw_rate"))):
            for name in (acc, rate):
                if name in data:
                    data[name] = data[name] * c[j, j]
        if cmap.frame != "FLU":
            report.mounting = {"frame": cmap.frame, "roll_deg": 0.0, "pitch_deg": 0.0,
                               "yaw_deg": 0.0,
                               "method": dict.fromkeys(("roll", "pitch", "yaw"), "given")}
        return
    acc_names, gyro_names = ("ax", "ay", "az"), ("roll_rate", "pitch_rate", "yaw_rate")
    groups = []
    for names in (acc_names, gyro_names):
        present = [n for n in names if n in data]
        if present and len(present) < 3:
            missing = [n for n in names if n not in data]
            raise ChannelMapError(
                f"[imu] frame {cmap.frame!r} with mounting rotates the sensor's axes into the "
                f"body's, so it needs all three of {', '.join(names)}; "
                f"{', '.join(missing)} missing from [channels]"
            )
        if present:
            groups.append(names)
    vec = {names: np.column_stack([data[n] for n in names]) @ c.T for names in groups}
    m = cmap.mounting
    angles = {"roll": m.roll_deg, "pitch": m.pitch_deg, "yaw": m.yaw_deg}
    method = dict.fromkeys(angles, "given")
    if m.auto:
        found, how = _auto_mounting(cmap, vec.get(acc_names), vec.get(gyro_names), data, grid,
                                    pose_streams, given=angles)
        for axis in m.auto:
            if not abs(found[axis]) <= AUTO_MOUNT_MAX_DEG:
                raise ChannelMapError(
                    f"[imu] mounting \"auto\" found {axis} = {found[axis]:.1f}°, beyond "
                    f"±{AUTO_MOUNT_MAX_DEG:.0f}°: a residual misalignment is a few degrees, so "
                    "the map's axes are likely wrong (check [imu] frame and the signs of the "
                    "IMU channels' expr against `vestim channels`); if the sensor really is "
                    f"turned that far, give the angles: mounting = {{{axis}_deg = …}}")
            angles[axis] = found[axis]
            method[axis] = how[axis]
    r = mounting_matrix(angles["roll"], angles["pitch"], angles["yaw"])
    for names, v in vec.items():
        body = v @ r.T
        for j, n in enumerate(names):
            data[n] = body[:, j]
    report.mounting = {"frame": cmap.frame, **{f"{k}_deg": v for k, v in angles.items()},
                       "method": method}


def _lowpass(x: np.ndarray, rate: float) -> np.ndarray:
    from scipy.signal import butter, filtfilt

    if rate / 2 <= AUTO_LOWPASS_HZ or len(x) < 16:
        return x
    b, a = butter(2, AUTO_LOWPASS_HZ / (rate / 2))
    return np.asarray(filtfilt(b, a, x, axis=0))


def _auto_mounting(cmap: ChannelMap, acc: np.ndarray | None, gyro: np.ndarray | None,
                   data: Mapping[str, np.ndarray], grid: np.ndarray,
                   pose_streams: Mapping[str, Stream], *, given: Mapping[str, float]
                   ) -> tuple[dict[str, float], dict[str, str]]:
    """Find the mounting angles from the data; returns ({roll, pitch, yaw} deg, {axis: method}).

    Pitch and yaw come from the direction of travel seen in the sensor's axes: the mean unit
    velocity of a pose (``travel = "pose"``, the default when a [pose] is given; openpilot's
    calibration does the same with its visual odometry), or, without one, pitch from mean
    gravity on straight and steady samples and yaw from the regression of the accelerometer
    on the wheel-speed derivative dω/dt (``travel = "wheels"``). Roll comes from mean
    gravity on straight and steady samples: the body's y axis is taken level there, so a
    road bank or crown goes into it.
    """
    if acc is None:
        raise ChannelMapError("[imu] mounting \"auto\" needs ax, ay and az")
    rate = cmap.rate
    acc_f = _lowpass(acc, rate)
    omegas = [data[n] for n in ch.WHEEL_SPEEDS if n in data]
    travel = cmap.travel or ("pose" if cmap.pose is not None else "wheels")
    steady = np.ones(len(grid), dtype=bool)
    if omegas:
        w = _lowpass(np.mean(omegas, axis=0), rate)
        dw = np.gradient(w, 1.0 / rate)
        steady &= np.abs(dw) < AUTO_STEADY_DOMEGA
    else:
        dw = None
    if gyro is not None:
        steady &= np.abs(_lowpass(gyro[:, 2], rate)) < AUTO_STRAIGHT_YAW_RATE
    elif "yaw_rate" in data:
        steady &= np.abs(_lowpass(data["yaw_rate"], rate)) < AUTO_STRAIGHT_YAW_RATE
    if dw is None and gyro is None and "yaw_rate" not in data:
        raise ChannelMapError(
            "[imu] mounting \"auto\" needs the wheel speeds or the yaw rate to find straight, "
            "steady driving"
        )
    if int(steady.sum()) < AUTO_MIN_SAMPLES:
        raise ChannelMapError(
            f"[imu] mounting \"auto\": only {int(steady.sum())} straight, steady samples "
            f"(|dω/dt| < {AUTO_STEADY_DOMEGA} rad/s², |yaw rate| < {AUTO_STRAIGHT_YAW_RATE} "
            f"rad/s); need {AUTO_MIN_SAMPLES}. Give the mounting angles instead"
        )
    gravity = acc_f[steady].mean(axis=0)  # specific force: body +z in sensor axes
    if travel == "pose":
        d = _pose_travel(cmap, pose_streams, grid)
        pitch, yaw = _angles_of_travel(d)
        how = {"pitch": "auto: pose travel direction", "yaw": "auto: pose travel direction"}
    else:
        if dw is None:
            raise ChannelMapError(
                "[imu] mounting \"auto\" without a [pose] needs the wheel speeds (omega_*) "
                "for the direction of travel"
            )
        # The yaw rate is the sensor's z rate.
        r = (_lowpass(gyro[:, 2], rate) if gyro is not None
             else _lowpass(data["yaw_rate"], rate))
        pitch, yaw = wheel_travel_angles(acc_f, gravity, w, dw, r)
        how = {"pitch": "auto: gravity on straight, steady samples",
               "yaw": "auto: accelerometer regression on wheel-speed dω/dt"}
    if "pitch" not in cmap.mounting.auto:
        pitch = given["pitch"]
    if "yaw" not in cmap.mounting.auto:
        yaw = given["yaw"]
    roll = _roll_from_gravity(gravity, pitch, yaw)
    how["roll"] = "auto: gravity on straight, steady samples"
    return {"roll": roll, "pitch": pitch, "yaw": yaw}, how


def wheel_travel_angles(acc_f: np.ndarray, gravity: np.ndarray, w: np.ndarray, dw: np.ndarray,
                        r: np.ndarray) -> tuple[float, float]:
    """(pitch_deg, yaw_deg) of the sensor from gravity and the accelerometer's response to dω/dt.

    ``acc_f`` (n, 3) is the low-passed specific force in the sensor's axes (m/s²), ``gravity``
    its mean on straight, steady samples (the body's up), ``w`` the low-passed mean wheel
    speed (rad/s, or m/s), ``dw`` its derivative and ``r`` the low-passed yaw rate (rad/s).
    a = c + b·dω/dt + e·ω̄·r: b is the longitudinal axis (scaled by R), e the lateral one;
    fitting e too keeps turns out of b. b is made level (perpendicular to ``gravity``).
    """
    up = gravity / np.linalg.norm(gravity)
    x = np.column_stack([np.ones(len(dw)), dw, w * r])
    coef, *_ = np.linalg.lstsq(x, acc_f, rcond=None)
    fwd = coef[1] - (coef[1] @ up) * up  # longitudinal response, made level
    if not np.linalg.norm(fwd) > 0:
        raise ChannelMapError("[imu] mounting \"auto\": the speed never changes; give the "
                              "yaw angle")
    fwd /= np.linalg.norm(fwd)
    left = np.cross(up, fwd)
    # Sensor x in body axes is the first row of [fwd; left; up] (body ← sensor).
    sx = np.array([fwd[0], left[0], up[0]])
    pitch = math.degrees(math.asin(-float(sx[2])))
    yaw = math.degrees(math.atan2(float(sx[1]), float(sx[0])))
    return pitch, yaw


def _roll_from_gravity(m: np.ndarray, pitch_deg: float, yaw_deg: float) -> float:
    """Roll (deg) that makes the mean specific force ``m`` (sensor axes) read ay = 0 in body axes.

    With R = R_min · Rx(r), body ay = a·Rx(r)·m with a = R_min^T e_y; that is
    A cos r + B sin r + K = 0, solved for the root nearest zero.
    """
    r0 = mounting_matrix(0.0, pitch_deg, yaw_deg)
    a = r0.T @ np.array([0.0, 1.0, 0.0])
    big_a = a[1] * m[1] + a[2] * m[2]
    big_b = a[2] * m[1] - a[1] * m[2]
    k = a[0] * m[0]
    amp = math.hypot(big_a, big_b)
    phi = math.atan2(big_b, big_a)
    c = max(-1.0, min(1.0, -k / amp))
    roots = [phi + math.acos(c), phi - math.acos(c)]
    roots = [math.remainder(x, 2 * math.pi) for x in roots]
    return math.degrees(min(roots, key=abs))


def pose_orientation(t: np.ndarray, orientation: tuple[Stream, Stream, Stream, Stream]) -> Any:
    """The pose's orientation at times ``t`` (s): a scipy ``Rotation`` of ``len(t)`` rotations.

    ``orientation`` holds the quaternion's (w, x, y, z) components, sampled at the same times;
    each sample is normalised, and between samples the rotation is interpolated along the
    great circle (``scipy.spatial.transform.Slerp``, constant angular rate), never component
    by component. Times outside the samples take the first or last orientation.

    Raises:
        ChannelMapError: components with different sample times, or a zero quaternion.
    """
    from scipy.spatial.transform import Rotation, Slerp

    tq = orientation[0].t
    if any(len(s.t) != len(tq) or not np.array_equal(s.t, tq) for s in orientation):
        raise ChannelMapError("[pose] orientation: the four components need the same sample times")
    q = np.column_stack([s.value for s in orientation])
    if not np.all(np.linalg.norm(q, axis=1) > 0):
        raise ChannelMapError("[pose] orientation holds a zero quaternion")
    keep = np.concatenate([[True], np.diff(tq) > 0])  # Slerp needs increasing times
    rot = Rotation.from_quat(q[keep], scalar_first=True)
    if len(rot) == 1:
        return Rotation.concatenate([rot] * len(t))
    return Slerp(tq[keep], rot)(np.clip(t, tq[keep][0], tq[keep][-1]))


def _pose_velocity(cmap: ChannelMap, pose_streams: Mapping[str, Stream]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(times, velocity in the pose frame's axes converted to FLU, m/s) at the pose's samples."""
    assert cmap.pose is not None
    pose = cmap.pose
    vs = [pose_streams[a] for a in pose.velocity]
    t = vs[0].t
    if any(len(s.t) != len(t) or not np.array_equal(s.t, t) for s in vs):
        raise ChannelMapError("[pose] velocity: the three components need the same sample times")
    conv = unit_factor(pose.velocity_unit, "ref_vx")
    v_world = np.column_stack([conv(s.value) for s in vs])
    w, x, y, z = (pose_streams[a] for a in pose.orientation)
    v_sensor = pose_orientation(t, (w, x, y, z)).apply(v_world, inverse=True)  # R(q)^T v
    return t, v_sensor @ frame_matrix(pose.frame).T


def _pose_travel(cmap: ChannelMap, pose_streams: Mapping[str, Stream], grid: np.ndarray
                 ) -> np.ndarray:
    """Mean unit velocity (sensor axes, FLU) over the pose samples in the log faster than 5 m/s."""
    t, v = _pose_velocity(cmap, pose_streams)
    speed = np.linalg.norm(v, axis=1)
    use = (t >= grid[0]) & (t <= grid[-1]) & (speed > AUTO_MIN_SPEED)
    if int(use.sum()) < 10:
        raise ChannelMapError(
            f"[imu] mounting \"auto\": only {int(use.sum())} pose samples faster than "
            f"{AUTO_MIN_SPEED} m/s; give the mounting angles instead"
        )
    d = (v[use] / speed[use, None]).mean(axis=0)
    return np.asarray(d / np.linalg.norm(d))


def _pose_reference(cmap: ChannelMap, pose_streams: Mapping[str, Stream], grid: np.ndarray,
                    report: ImportReport) -> dict[str, np.ndarray]:
    """ref_vx, ref_vy: the pose velocity in body axes (through the IMU's mounting), on the grid.

    The pose is taken to be the IMU's own frame (one device, as comma's EON). The velocity is
    rotated at the pose's samples and then interpolated linearly; no lever arm is applied.
    """
    t, v = _pose_velocity(cmap, pose_streams)
    m = report.mounting or {"roll_deg": 0.0, "pitch_deg": 0.0, "yaw_deg": 0.0}
    body = v @ mounting_matrix(m["roll_deg"], m["pitch_deg"], m["yaw_deg"]).T
    return {"ref_vx": np.interp(grid, t, body[:, 0]), "ref_vy": np.interp(grid, t, body[:, 1])}


def describe_report(report: ImportReport) -> list[str]:
    """Human-readable lines of a report (for the CLI)."""
    lines = []
    if report.mounting is not None:
        m = report.mounting
        how = m.get("method", {})
        angles = ", ".join(f"{axis} {m[f'{axis}_deg']:.3f}° ({how.get(axis, 'given')})"
                           for axis in ("roll", "pitch", "yaw"))
        lines.append(f"IMU frame {m['frame']}, mounting {angles}")
    for g in report.gaps:
        kind = "sparse " if g.sparse else ""
        lines.append(f"gap: {kind}channel {g.channel} ({g.address}) silent {g.length:.3g} s "
                     f"from t = {g.start:.6g} s")
    if report.trimmed is not None:
        lines.append(f"kept t = {report.trimmed[0]:.6g} … {report.trimmed[1]:.6g} s (gaps = trim)")
    return lines

