"""Vehicle files: built-ins against the papers, and every rejection naming ``[table] key``."""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from vestim.constants import G
from vestim.errors import VehicleFileError
from vestim.io import Vehicle, load_vehicle
from vestim.io.vehicle import BUILTIN_VEHICLES, default_suspension, vehicle_from_dict


def _builtin_dict(name: str = "hashemi_suv") -> dict[str, Any]:
    text = (resources.files("vestim") / "data" / "vehicles" / f"{name}.toml").read_text(
        encoding="utf-8"
    )
    return tomllib.loads(text)


@pytest.mark.parametrize("name", BUILTIN_VEHICLES)
def test_builtins_load(name: str) -> None:
    vehicle = load_vehicle(name)
    assert isinstance(vehicle, Vehicle)
    assert vehicle.name == name
    assert vehicle.body.drivetrain in ("awd", "fwd", "rwd")


def test_hashemi_suv_matches_table_i_and_001_sec_v() -> None:
    """Golden values typed from the papers, not from the TOML file.

    [vehicle]: 000 Table I = 001 Table I. [tire]: 001 Sec. V (road experiments).
    Exact equality: the TOML holds the papers' decimal literals.
    """
    v = load_vehicle("hashemi_suv")
    body = {
        "mass": 2270.0, "yaw_inertia": 4650.0, "wheel_inertia": 1.68, "lf": 1.42, "lr": 1.43,
        "track_f": 1.62, "track_r": 1.56, "cg_height": 0.65, "roll_center_height": 0.54,
        "wheel_radius": 0.33,
    }
    for key, value in body.items():
        assert getattr(v.body, key) == value, key
    assert v.body.wheelbase == pytest.approx(2.85, abs=1e-12)  # Table I: L_wb = 2.85 m
    assert v.body.drivetrain == "awd"  # four independent in-wheel motors
    tire = {
        "sigma0_x": 632.1, "sigma1_x": 0.76, "sigma2_x": 0.0016, "kappa_x": 8.32,
        "sigma0_y": 181.5, "sigma1_y": 0.81, "sigma2_y": 0.001, "kappa_y": 12.84,
    }
    for key, value in tire.items():
        assert getattr(v.tire, key) == value, key


def test_load_from_path(tmp_path: Path) -> None:
    path = tmp_path / "my_car.toml"
    path.write_text(
        (resources.files("vestim") / "data" / "vehicles" / "compact_car.toml").read_text(
            encoding="utf-8"
        ),
        encoding="utf-8",
    )
    vehicle = load_vehicle(path)
    assert vehicle.name == "my_car"
    assert vehicle == replace(load_vehicle("compact_car"), name="my_car")


def test_missing_optional_tables_take_documented_defaults() -> None:
    """compact_car has no [suspension]: roll mode at 1.5 Hz, ζ = 0.5 (module docstring)."""
    v = load_vehicle("compact_car")
    assert v.suspension == vehicle_from_dict(_builtin_dict("compact_car")).suspension
    assert v.suspension.roll_inertia == pytest.approx(0.2 * v.body.yaw_inertia)
    s, b = v.suspension, v.body
    # k = I ωn² + m g (h - h_rc): the pendulum term is removed before taking the frequency.
    k_elastic = s.roll_stiffness - b.mass * G * (b.cg_height - b.roll_center_height)
    assert math.sqrt(k_elastic / s.roll_inertia) / (2 * math.pi) == pytest.approx(1.5)
    assert s.roll_damping / (2 * math.sqrt(s.roll_stiffness * s.roll_inertia)) == (
        pytest.approx(0.5)
    )
    assert default_suspension(b)["roll_stiffness_front_share"] == 0.55


def test_given_records_the_stated_tables_and_estimators_see_no_default_drag() -> None:
    """A file without [aerodynamics] keeps the simulator's defaults in ``aerodynamics`` but
    ``stated_aerodynamics`` has no drag and no rolling resistance (000 eq. (1)): the
    defaults describe vestim's simulated car (0.9 m², f = 0.012), not the user's."""
    data = _builtin_dict()
    full = vehicle_from_dict(data)
    assert {"suspension", "aerodynamics", "powertrain", "magic_formula"} <= full.given
    assert full.stated_aerodynamics == full.aerodynamics
    del data["aerodynamics"]
    bare = vehicle_from_dict(data)
    assert "aerodynamics" not in bare.given
    assert bare.aerodynamics.rolling_resistance == 0.012
    assert bare.stated_aerodynamics.rolling_resistance == 0.0
    assert bare.stated_aerodynamics.drag_area == 0.0


def test_stiffness_table_is_optional() -> None:
    assert load_vehicle("hashemi_suv").stiffness is None
    data = _builtin_dict()
    data["stiffness"] = {"cx_f": 2.0e5, "cx_r": 2.0e5, "cy_f": 1.2e5, "cy_r": 1.4e5}
    stiffness = vehicle_from_dict(data).stiffness
    assert stiffness is not None and stiffness.cy_r == 1.4e5


def test_with_drivetrain() -> None:
    v = load_vehicle("hashemi_suv")
    assert v.with_drivetrain("rwd").body.drivetrain == "rwd"
    assert v.body.drivetrain == "awd"  # frozen: the original is unchanged
    with pytest.raises(VehicleFileError, match="drivetrain '4wd'"):
        v.with_drivetrain("4wd")


def _set(table: str, key: str, value: Any) -> Any:
    def edit(d: dict[str, Any]) -> None:
        d[table][key] = value
    return edit


def _delete(table: str, key: str | None = None) -> Any:
    def edit(d: dict[str, Any]) -> None:
        if key is None:
            del d[table]
        else:
            del d[table][key]
    return edit


def _add_table(d: dict[str, Any]) -> None:
    d["brakes"] = {"disc": 0.3}


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        pytest.param(_add_table, r"unknown table\(s\) \[brakes\]", id="unknown-table"),
        pytest.param(_set("vehicle", "colour", 1.0), r"\[vehicle\] has unknown key\(s\) colour",
                     id="unknown-key"),
        pytest.param(_set("suspension", "spring", 1.0), r"\[suspension\] .*unknown.* spring",
                     id="unknown-key-optional-table"),
        pytest.param(_delete("tire", "kappa_y"), r"\[tire\] kappa_y is missing",
                     id="missing-key"),
        pytest.param(_delete("tire"), r"\[tire\] table is missing", id="missing-table"),
        pytest.param(_set("vehicle", "mass", "heavy"),
                     r"\[vehicle\] mass = 'heavy' must be a number", id="wrong-type"),
        pytest.param(_set("vehicle", "mass", True), r"\[vehicle\] mass = True must be a number",
                     id="bool-is-not-a-number"),
        pytest.param(_set("vehicle", "mass", -2270.0), r"\[vehicle\] mass = -2270\.0 must be > 0",
                     id="negative-mass"),
        pytest.param(_set("vehicle", "mass", 10**400), r"\[vehicle\] mass = inf must be finite",
                     id="huge-int"),
        pytest.param(_set("vehicle", "drivetrain", "4wd"),
                     r"\[vehicle\] drivetrain = '4wd'; use one of 'awd', 'fwd', 'rwd'",
                     id="bad-drivetrain"),
        pytest.param(_set("tire", "mu_c", 1.3), r"\[tire\] mu_c = 1\.3 exceeds mu_s = 1\.2",
                     id="mu_c-above-mu_s"),
        pytest.param(_set("vehicle", "roll_center_height", 0.7),
                     r"\[vehicle\] roll_center_height = 0\.7 m is not below cg_height",
                     id="roll-centre-above-cg"),
        pytest.param(_set("powertrain", "front_drive_share", 1.5),
                     r"\[powertrain\] front_drive_share = 1\.5 must lie in \[0, 1\]",
                     id="fraction"),
        pytest.param(_set("magic_formula", "e_x", 1.0),
                     r"\[magic_formula\] e_x = 1\.0 must be < 1", id="mf-curvature"),
        pytest.param(_set("vehicle", "lf", 0), r"\[vehicle\] lf = 0\.0 must be > 0",
                     id="zero-length"),
    ],
)
def test_invalid_content_names_table_and_key(edit: Any, match: str) -> None:
    data = copy.deepcopy(_builtin_dict())
    edit(data)
    with pytest.raises(VehicleFileError, match=match):
        vehicle_from_dict(data)


def test_table_must_be_a_table() -> None:
    data = _builtin_dict()
    data["tire"] = 3.0
    with pytest.raises(VehicleFileError, match=r"\[tire\] must be a table"):
        vehicle_from_dict(data)


def test_file_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(VehicleFileError, match=r"nope\.toml.* not found.*hashemi_suv"):
        load_vehicle(tmp_path / "nope.toml")
    broken = tmp_path / "broken.toml"
    broken.write_text("[vehicle\nmass = 1\n", encoding="utf-8")
    with pytest.raises(VehicleFileError, match=r"broken\.toml: not valid TOML"):
        load_vehicle(broken)
    bad = tmp_path / "bad.toml"
    bad.write_text("[vehicle]\nmass = 1.0\n[tire]\n", encoding="utf-8")
    with pytest.raises(VehicleFileError, match=r"bad\.toml: \[vehicle\] yaw_inertia is missing"):
        load_vehicle(bad)
