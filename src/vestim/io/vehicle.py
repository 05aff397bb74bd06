"""Vehicle TOML files → frozen, validated parameter objects.

The file format is fixed by docs/format.md ("Vehicle file"):
``[vehicle]`` and ``[tire]`` are required and every key in them is required;
``[stiffness]`` is optional for the stiffness estimator. The simulator reads
four further optional tables, each with documented defaults:

``[suspension]``    roll and pitch modes of the sprung body
``[aerodynamics]``  drag and rolling resistance
``[powertrain]``    torque limits, torque split, brake balance
``[magic_formula]`` the combined-slip Magic Formula tire plant

and ``vestim calibrate`` adds ``[calibration.*]`` tables of identified values
(:mod:`vestim.io.calibration`).

Any other table, an unknown key, a missing required key, a wrong type, a
non-physical value or one outside its plausible range (a field's ``range``
metadata, :data:`vestim.io.calibration.RANGES` for ``[calibration.*]``) raises
:class:`~vestim.errors.VehicleFileError` that names ``[table] key`` and says what
is expected. All values are SI.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any, Literal, TypeVar

from vestim.constants import G
from vestim.errors import VehicleFileError
from vestim.io.calibration import Calibration, length_unit, parse_calibration

Drivetrain = Literal["awd", "fwd", "rwd"]
DRIVETRAINS: tuple[str, ...] = ("awd", "fwd", "rwd")

# Constraint tags carried in field metadata; checked once, in one place.
_POS = {"check": "positive"}
_NONNEG = {"check": "nonnegative"}
_FRAC = {"check": "fraction"}


Range = tuple[float, float, str]
"""A plausible range (low, high, the likely mistake and fix) of a value: beyond every road
vehicle in SI units, while the usual wrong unit (per cent, km/h, g/cm³) lands outside it."""


def _pos(doc: str = "", rng: Range | None = None) -> Any:
    return field(metadata={**_POS, "doc": doc, "range": rng})


def _nonneg(doc: str = "", rng: Range | None = None) -> Any:
    return field(metadata={**_NONNEG, "doc": doc, "range": rng})


def _frac(doc: str = "") -> Any:
    return field(metadata={**_FRAC, "doc": doc})


def _tagged(check: str, doc: str = "") -> Any:
    # Through a helper like the others, so mypy sees every field of a table alike.
    return field(metadata={"check": check, "doc": doc})


@dataclass(frozen=True)
class VehicleBody:
    """``[vehicle]``: chassis geometry and inertia (000/001 Table I)."""

    mass: float = _pos("kg")
    yaw_inertia: float = _pos("kg m^2")
    wheel_inertia: float = _pos("kg m^2, one wheel")
    lf: float = _pos("m, CG to front axle")
    lr: float = _pos("m, CG to rear axle")
    track_f: float = _pos("m")
    track_r: float = _pos("m")
    cg_height: float = _pos("m")
    roll_center_height: float = _nonneg("m")
    wheel_radius: float = _pos("m, effective rolling radius")
    steering_ratio: float = _pos("steering-wheel angle / road-wheel angle",
                                 (1.0, 40.0, "a car's is 12–20 (1 when the steering column "
                                  "holds road-wheel angles)"))
    drivetrain: str = field(default="awd", metadata={"check": "drivetrain"})

    @property
    def wheelbase(self) -> float:
        """lf + lr in m."""
        return self.lf + self.lr

    def _check(self) -> None:
        _check_magnitudes(self)
        if self.roll_center_height >= self.cg_height:
            raise VehicleFileError(
                f"[vehicle] roll_center_height = {self.roll_center_height} m is not below "
                f"cg_height = {self.cg_height} m; the roll axis must lie below the CG"
            )


# Magnitude limits of [vehicle]: each lies beyond every road vehicle in SI units, yet a value in
# the usual wrong unit (mm, cm, g, t) lands beyond it by a factor of ten or more.
RADIUS_MAX = 2.0
"""m; the largest road-vehicle tyres (mining trucks) have a 2 m radius; a car's 0.33 m in mm
reads 330, in cm 33."""
LENGTH_MAX = 20.0
"""m; lf, lr, track_f, track_r, cg_height, roll_center_height of a road vehicle are below 20 m
(a 1.42 m lf reads 1420 in mm, 142 in cm)."""
MASS_RANGE = (50.0, 100_000.0)
"""kg; a road vehicle weighs 50 kg (a light quadricycle's unladen mass is more) to 100 t; a
1650 kg car reads 1.65 in tonnes and 1 650 000 in grams."""


def _check_magnitudes(body: VehicleBody) -> None:
    """Wrong-unit magnitudes of ``[vehicle]`` (a radius in mm, a mass in g or t)."""
    r = body.wheel_radius
    if r > RADIUS_MAX:
        raise VehicleFileError(
            f"[vehicle] wheel_radius = {r:g} m is beyond {RADIUS_MAX:g} m (no road tyre is that "
            f"large): this looks like {length_unit(r, 0.35)}; give it in metres"
        )
    for name in ("lf", "lr", "track_f", "track_r", "cg_height", "roll_center_height"):
        v = getattr(body, name)
        if v > LENGTH_MAX:
            raise VehicleFileError(
                f"[vehicle] {name} = {v:g} m is beyond {LENGTH_MAX:g} m: this looks like "
                f"{length_unit(v, 1.0)}; give it in metres"
            )
    lo, hi = MASS_RANGE
    if body.mass < lo:
        raise VehicleFileError(
            f"[vehicle] mass = {body.mass:g} kg is below {lo:g} kg: this looks like tonnes "
            f"({body.mass:g} t = {body.mass * 1000:g} kg); give it in kg"
        )
    if body.mass > hi:
        raise VehicleFileError(
            f"[vehicle] mass = {body.mass:.10g} kg is beyond {hi:g} kg: this looks like grams "
            f"({body.mass:.10g} g = {body.mass / 1000:g} kg); give it in kg"
        )


_MU_RANGE: Range = (0.0, 3.0, "a normalised friction coefficient (up to 1.3 on a dry road); "
                   "a value like 120 is per cent: divide by 100")


@dataclass(frozen=True)
class LuGreTire:
    """``[tire]``: average lumped LuGre parameters (004 eq. (6)–(7), 001 Sec. V)."""

    sigma0_x: float = _pos("1/m, rubber stiffness")
    sigma1_x: float = _nonneg("s/m, rubber damping")
    sigma2_x: float = _nonneg("s/m, relative viscous damping")
    kappa_x: float = _pos("1/m, load distribution factor")
    sigma0_y: float = _pos("1/m")
    sigma1_y: float = _nonneg("s/m")
    sigma2_y: float = _nonneg("s/m")
    kappa_y: float = _pos("1/m")
    mu_s: float = _pos("static friction (normalised)", _MU_RANGE)
    mu_c: float = _pos("Coulomb friction (normalised)", _MU_RANGE)
    v_s: float = _pos("m/s, Stribeck velocity", (0.0, 100.0, "a Stribeck velocity in m/s "
                                                  "(1–10); km/h would be 3.6 × larger"))
    alpha: float = _pos("Stribeck exponent", (0.0, 10.0, "a Stribeck exponent (0.5–2)"))

    def _check(self) -> None:
        if self.mu_c > self.mu_s:
            raise VehicleFileError(
                f"[tire] mu_c = {self.mu_c} exceeds mu_s = {self.mu_s}; "
                "Coulomb friction must not exceed static friction"
            )


@dataclass(frozen=True)
class Stiffness:
    """``[stiffness]``: nominal axle-total tire stiffness for the stiffness estimator."""

    cx_f: float = _pos("N per unit slip ratio, front axle")
    cx_r: float = _pos("N per unit slip ratio, rear axle")
    cy_f: float = _pos("N/rad, front axle")
    cy_r: float = _pos("N/rad, rear axle")


@dataclass(frozen=True)
class Suspension:
    """``[suspension]``: sprung-body roll and pitch as damped second-order modes.

    Defaults (used for a missing table or key): ``roll_inertia`` = 0.2·yaw_inertia,
    ``pitch_inertia`` = 0.8·yaw_inertia, stiffness for a 1.5 Hz mode plus the
    gravity (pendulum) term, damping ratio 0.5, 55 % of the roll stiffness on
    the front axle, pitch centre at ground level. See :func:`default_suspension`.
    """

    roll_inertia: float = _pos("kg m^2, sprung body about the roll axis")
    pitch_inertia: float = _pos("kg m^2, sprung body about the pitch axis")
    roll_stiffness: float = _pos("N m/rad, total")
    roll_damping: float = _nonneg("N m s/rad, total")
    pitch_stiffness: float = _pos("N m/rad")
    pitch_damping: float = _nonneg("N m s/rad")
    roll_stiffness_front_share: float = _frac("share of roll stiffness and damping at the front")
    pitch_center_height: float = _nonneg("m")


@dataclass(frozen=True)
class Aerodynamics:
    """``[aerodynamics]``: drag and rolling resistance (defaults: 0.9 m², 1.2 kg/m³, 0.012)."""

    drag_area: float = _nonneg("m^2, drag coefficient times frontal area",
                               (0.0, 20.0, "Cd·A in m² (0.5–1.2 for a car; Cd alone is "
                                "0.25–0.4)"))
    air_density: float = _pos("kg/m^3", (0.5, 2.0, "air density in kg/m³ (1.2 at sea level)"))
    rolling_resistance: float = _nonneg("rolling-resistance coefficient (moment = f R Fz)",
                                        (0.0, 0.1, "a rolling-resistance coefficient "
                                         "(0.008–0.02); 1.2 looks like per cent"))


@dataclass(frozen=True)
class Powertrain:
    """``[powertrain]``: wheel-torque limits and splits, used by the simulator's pedal maps
    and (the two shares only) by the force stage for logs without wheel torques, where the
    chassis-equation total is distributed over the axles (:mod:`vestim.models.chassis`).

    Defaults: 0.45·m·g·R of drive torque at the wheels, 60 W/kg of power,
    AWD front share 0.5, 1.0·m·g·R of brake torque, 65 % of it at the front,
    drive torque fading to zero over the last 10 % below a wheel-periphery speed
    of 50 m/s (the motor's speed limit; it bounds wheel spin on ice).
    """

    max_drive_torque: float = _pos("N m, all driven wheels together")
    max_power: float = _pos("W at the wheels")
    front_drive_share: float = _frac("AWD only: share of drive torque at the front axle")
    max_brake_torque: float = _pos("N m, all wheels together")
    brake_front_share: float = _frac("share of brake torque at the front axle")
    max_speed: float = _pos("m/s of wheel periphery at which drive torque has faded to zero",
                            (0.0, 150.0, "a speed in m/s (150 m/s = 540 km/h); km/h would "
                             "be 3.6 × larger"))


@dataclass(frozen=True)
class MagicFormula:
    """``[magic_formula]``: combined-slip Magic Formula plant (see :mod:`vestim.models.tire`).

    Peak factor D = μ·Fz comes from the road, not from this table. Defaults are a
    generic passenger-car tire; see :func:`vestim.models.tire.magic_formula`.
    """

    fz0: float = _pos("N, nominal load")
    c_x: float = _pos("shape factor, longitudinal")
    e_x: float = _tagged("e_factor", "curvature, longitudinal (< 1)")
    kx: float = _pos("longitudinal slip stiffness / Fz at fz0, per unit slip ratio")
    kx_load: float = _tagged("any", "relative change of kx/Fz per dfz")
    c_y: float = _pos("shape factor, lateral")
    e_y: float = _tagged("e_factor", "curvature, lateral (< 1)")
    ky1: float = _pos("peak cornering stiffness / fz0, per rad")
    ky2: float = _pos("load (in fz0) at which cornering stiffness peaks, PAC2002 pKy2")
    rbx1: float = _pos("combined-slip weighting, Fx reduced by slip angle")
    rbx2: float = _nonneg("combined-slip weighting")
    rby1: float = _pos("combined-slip weighting, Fy reduced by slip ratio")
    rby2: float = _nonneg("combined-slip weighting")
    relax_x: float = _pos("m, longitudinal relaxation length")
    relax_y: float = _pos("m, lateral relaxation length")
    damping_x: float = _nonneg("s/m, carcass damping / Fz on the longitudinal deflection rate")
    damping_y: float = _nonneg("s/m, carcass damping / Fz on the lateral deflection rate")


@dataclass(frozen=True)
class Vehicle:
    """A whole vehicle file. ``stiffness`` is ``None`` when the file has no such table.

    ``given`` names the optional tables the file itself stated (the others hold their
    documented defaults, made for vestim's simulator: an estimator must not treat them as
    facts about the car).
    """

    body: VehicleBody
    tire: LuGreTire
    suspension: Suspension
    aerodynamics: Aerodynamics
    powertrain: Powertrain
    magic_formula: MagicFormula
    stiffness: Stiffness | None = None
    name: str = "vehicle"
    given: frozenset[str] = frozenset()
    calibration: Calibration | None = None

    @property
    def stated_aerodynamics(self) -> Aerodynamics:
        """``[aerodynamics]`` as the estimators use it: the file's table, or no drag and no
        rolling resistance (000 eq. (1)) when the file does not state one — the defaults
        describe vestim's simulated car, not the user's."""
        if "aerodynamics" in self.given:
            return self.aerodynamics
        return replace(self.aerodynamics, drag_area=0.0, rolling_resistance=0.0)

    def with_drivetrain(self, drivetrain: str) -> Vehicle:
        """Copy with another drivetrain ("awd" | "fwd" | "rwd")."""
        if drivetrain not in DRIVETRAINS:
            raise VehicleFileError(
                f"drivetrain {drivetrain!r} is not one of {', '.join(DRIVETRAINS)}"
            )
        return replace(self, body=replace(self.body, drivetrain=drivetrain))


_T = TypeVar("_T")


def _parse(cls: type[_T], table: str, data: Any, defaults: dict[str, float] | None) -> _T:
    """Build one frozen table object, naming ``[table] key`` in every error."""
    if not isinstance(data, dict):
        raise VehicleFileError(f"[{table}] must be a table, got {type(data).__name__}")
    known = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise VehicleFileError(
            f"[{table}] has unknown key(s) {', '.join(unknown)}; allowed: {', '.join(known)}"
        )
    values: dict[str, Any] = {}
    for name, f in known.items():
        check = f.metadata.get("check", "any")
        if name in data:
            raw = data[name]
        elif defaults is not None and name in defaults:
            raw = defaults[name]
        else:
            raise VehicleFileError(
                f"[{table}] {name} is missing; add it ({f.metadata.get('doc', '')})"
            )
        if check == "drivetrain":
            if raw not in DRIVETRAINS:
                raise VehicleFileError(
                    f"[{table}] {name} = {raw!r}; use one of {', '.join(map(repr, DRIVETRAINS))}"
                )
            values[name] = raw
            continue
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise VehicleFileError(
                f"[{table}] {name} = {raw!r} must be a number ({f.metadata.get('doc', '')})"
            )
        try:
            value = float(raw)
        except OverflowError:  # TOML integers are unbounded in tomllib
            value = math.inf
        problem = None
        if not math.isfinite(value):
            problem = "must be finite"
        elif check == "positive" and value <= 0:
            problem = "must be > 0"
        elif check == "nonnegative" and value < 0:
            problem = "must be >= 0"
        elif check == "fraction" and not 0.0 <= value <= 1.0:
            problem = "must lie in [0, 1]"
        elif check == "e_factor" and value >= 1.0:
            problem = "must be < 1 (Magic Formula curvature)"
        if problem:
            raise VehicleFileError(
                f"[{table}] {name} = {value} {problem} ({f.metadata.get('doc', '')})"
            )
        rng = f.metadata.get("range")
        if rng is not None and not rng[0] <= value <= rng[1]:
            raise VehicleFileError(
                f"[{table}] {name} = {value:g} is outside the plausible range [{rng[0]:g}, "
                f"{rng[1]:g}] ({f.metadata.get('doc', '')}); {rng[2]}"
            )
        values[name] = value
    obj = cls(**values)
    check_fn = getattr(obj, "_check", None)
    if check_fn is not None:
        check_fn()
    return obj


def default_suspension(body: VehicleBody) -> dict[str, float]:
    """Defaults of ``[suspension]`` derived from ``[vehicle]`` (1.5 Hz modes, ζ = 0.5)."""
    wn = 2.0 * math.pi * 1.5
    ix = 0.2 * body.yaw_inertia
    iy = 0.8 * body.yaw_inertia
    k_roll = ix * wn**2 + body.mass * G * (body.cg_height - body.roll_center_height)
    k_pitch = iy * wn**2 + body.mass * G * body.cg_height
    return {
        "roll_inertia": ix,
        "pitch_inertia": iy,
        "roll_stiffness": k_roll,
        "roll_damping": 2.0 * 0.5 * math.sqrt(k_roll * ix),
        "pitch_stiffness": k_pitch,
        "pitch_damping": 2.0 * 0.5 * math.sqrt(k_pitch * iy),
        "roll_stiffness_front_share": 0.55,
        "pitch_center_height": 0.0,
    }


def default_aerodynamics() -> dict[str, float]:
    """Defaults of ``[aerodynamics]``."""
    return {"drag_area": 0.9, "air_density": 1.2, "rolling_resistance": 0.012}


def default_powertrain(body: VehicleBody) -> dict[str, float]:
    """Defaults of ``[powertrain]`` derived from ``[vehicle]``."""
    weight_moment = body.mass * G * body.wheel_radius
    return {
        "max_drive_torque": 0.45 * weight_moment,
        "max_power": 60.0 * body.mass,
        "front_drive_share": 0.5,
        "max_brake_torque": 1.0 * weight_moment,
        "brake_front_share": 0.65,
        "max_speed": 50.0,
    }


def default_magic_formula() -> dict[str, float]:
    """Defaults of ``[magic_formula]``: a generic passenger-car tire (PAC2002-like shape)."""
    return {
        "fz0": 4000.0,
        "c_x": 1.65,
        "e_x": 0.1,
        "kx": 20.0,
        "kx_load": -0.1,
        "c_y": 1.3,
        "e_y": -0.5,
        "ky1": 16.0,
        "ky2": 1.8,
        "rbx1": 12.0,
        "rbx2": 10.0,
        "rby1": 10.0,
        "rby2": 10.0,
        "relax_x": 0.15,
        "relax_y": 0.4,
        "damping_x": 0.6,
        "damping_y": 0.6,
    }


_TABLES = ("vehicle", "tire", "stiffness", "suspension", "aerodynamics", "powertrain",
           "magic_formula", "calibration")


def vehicle_from_dict(data: dict[str, Any], name: str = "vehicle") -> Vehicle:
    """Validate a parsed TOML document; see the module docstring for the tables."""
    unknown = sorted(set(data) - set(_TABLES))
    if unknown:
        raise VehicleFileError(
            f"unknown table(s) {', '.join('[' + u + ']' for u in unknown)}; "
            f"allowed: {', '.join('[' + t + ']' for t in _TABLES)}"
        )
    for required in ("vehicle", "tire"):
        if required not in data:
            raise VehicleFileError(f"[{required}] table is missing; the spec requires it")
    body = _parse(VehicleBody, "vehicle", data["vehicle"], None)
    return Vehicle(
        body=body,
        tire=_parse(LuGreTire, "tire", data["tire"], None),
        suspension=_parse(Suspension, "suspension", data.get("suspension", {}),
                          default_suspension(body)),
        aerodynamics=_parse(Aerodynamics, "aerodynamics", data.get("aerodynamics", {}),
                            default_aerodynamics()),
        powertrain=_parse(Powertrain, "powertrain", data.get("powertrain", {}),
                          default_powertrain(body)),
        magic_formula=_parse(MagicFormula, "magic_formula", data.get("magic_formula", {}),
                             default_magic_formula()),
        stiffness=(_parse(Stiffness, "stiffness", data["stiffness"], None)
                   if "stiffness" in data else None),
        name=name,
        given=frozenset(t for t in _TABLES if t in data and t not in ("vehicle", "tire")),
        calibration=_calibration(data["calibration"], body) if "calibration" in data else None,
    )


RADIUS_RATIO = (0.8, 1.25)
"""A calibrated wheel radius over ``[vehicle] wheel_radius``: load, pressure and wear move a
tyre's effective radius by a few per cent; 20 % off is another tyre or another unit."""


def _calibration(table: Any, body: VehicleBody) -> Calibration:
    """``[calibration]`` (its own ranges, :data:`vestim.io.calibration.RANGES`), and the
    calibrated radii against ``[vehicle] wheel_radius``."""
    cal = parse_calibration(table)
    lo, hi = RADIUS_RATIO
    for c in ("fl", "fr", "rl", "rr"):
        r = cal.get("wheels", f"radius_{c}")
        if r is not None and not lo <= r.value / body.wheel_radius <= hi:
            raise VehicleFileError(
                f"[calibration.wheels] radius_{c} = {r.value:g} m is "
                f"{r.value / body.wheel_radius:.3g} × [vehicle] wheel_radius = "
                f"{body.wheel_radius:g} m, outside the plausible {lo:g}–{hi:g}: check both "
                "values (or recalibrate from logs of this car)")
    return cal


BUILTIN_VEHICLES: tuple[str, ...] = ("hashemi_suv", "compact_car")


def load_vehicle(path: str | Path) -> Vehicle:
    """Load a vehicle file, or a built-in by name (``hashemi_suv``, ``compact_car``).

    Raises:
        VehicleFileError: unreadable file, TOML syntax error, or invalid content
            (the message names the file and ``[table] key``).
    """
    p = Path(path)
    if not p.exists() and str(path) in BUILTIN_VEHICLES:
        text = (resources.files("vestim") / "data" / "vehicles" / f"{path}.toml").read_text()
        source = f"built-in vehicle {path!r}"
        name = str(path)
    else:
        if not p.is_file():
            raise VehicleFileError(
                f"vehicle file {str(p)!r} not found; give a TOML path or one of "
                f"{', '.join(BUILTIN_VEHICLES)}"
            )
        try:
            # utf-8-sig: a byte-order mark (Windows editors) is not part of the TOML.
            text = p.read_text(encoding="utf-8-sig")
        except (UnicodeDecodeError, OSError) as exc:
            raise VehicleFileError(f"{p}: cannot be read as UTF-8 text: {exc}") from exc
        source = str(p)
        name = p.stem
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise VehicleFileError(f"{source}: not valid TOML: {exc}") from exc
    try:
        return vehicle_from_dict(data, name=name)
    except VehicleFileError as exc:
        raise VehicleFileError(f"{source}: {exc}") from exc
