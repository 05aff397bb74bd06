"""From a folder of raw recordings to estimates (issue 28, "Must show").

Starting from nothing but the repository: ``vestim simulate`` makes two short logs (4 s at
200 Hz); each becomes an MDF4 file of raw CAN frames, encoded with cantools from a DBC of our
own (Motorola and Intel signals, ``1/min`` wheel speeds, accelerations in ``g``, a clockwise
yaw rate in ``dps``, multiplexed torques in ``Nm``) and written with python-can's
``MF4Writer``, and a ROS 2 bag written with rosbags. Then ``vestim channels`` lists them,
``vestim import`` converts one, and ``vestim batch --map`` estimates the whole folder; every
estimate equals the Parquet route's to within 0.01 σ.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vestim.cli import app
from vestim.io import read_log

can = pytest.importorskip("can")
cantools = pytest.importorskip("cantools")
pytest.importorskip("asammdf")
pytest.importorskip("rosbags")

SECONDS = 4.0
DBC = """VERSION ""

BU_: ECU VESTIM

BO_ 256 WHEELS_F: 8 ECU
 SG_ WhlSpd_FL : 0|32@1- (0.0001,0) [-100000|100000] "1/min" VESTIM
 SG_ WhlSpd_FR : 32|32@1- (0.0001,0) [-100000|100000] "1/min" VESTIM

BO_ 257 WHEELS_R: 8 ECU
 SG_ WhlSpd_RL : 0|32@1- (0.0001,0) [-100000|100000] "1/min" VESTIM
 SG_ WhlSpd_RR : 32|32@1- (0.0001,0) [-100000|100000] "1/min" VESTIM

BO_ 272 TORQUES: 8 ECU
 SG_ TrqMux M : 0|8@1+ (1,0) [0|1] "" VESTIM
 SG_ Trq_FL m0 : 8|28@1- (0.0001,0) [-13000|13000] "Nm" VESTIM
 SG_ Trq_FR m0 : 36|28@1- (0.0001,0) [-13000|13000] "Nm" VESTIM
 SG_ Trq_RL m1 : 8|28@1- (0.0001,0) [-13000|13000] "Nm" VESTIM
 SG_ Trq_RR m1 : 36|28@1- (0.0001,0) [-13000|13000] "Nm" VESTIM

BO_ 288 IMU_ACC_XY: 8 ECU
 SG_ LongAccel : 7|32@0- (1e-06,0) [-2|2] "g" VESTIM
 SG_ LatAccel : 39|32@0- (1e-06,0) [-2|2] "g" VESTIM

BO_ 289 IMU_ACC_Z: 4 ECU
 SG_ VertAccel : 7|32@0- (1e-06,0) [-3|3] "g" VESTIM

BO_ 290 IMU_RATES_A: 8 ECU
 SG_ YawRateCW : 7|32@0- (1e-05,0) [-1000|1000] "dps" VESTIM
 SG_ RollRate : 39|32@0- (1e-05,0) [-1000|1000] "dps" VESTIM

BO_ 291 IMU_RATES_B: 4 ECU
 SG_ PitchRate : 7|32@0- (1e-05,0) [-1000|1000] "dps" VESTIM

BO_ 304 STEER: 4 ECU
 SG_ SteeringWheelAngle : 0|32@1- (1e-05,0) [-2000|2000] "deg" VESTIM

BO_ 305 ROAD_WHEEL: 8 ECU
 SG_ RoadWheelAngle_FL : 0|32@1- (1e-06,0) [-90|90] "deg" VESTIM
 SG_ RoadWheelAngle_FR : 32|32@1- (1e-06,0) [-90|90] "deg" VESTIM
"""
RPM, DEG, G = 60.0 / (2.0 * math.pi), 180.0 / math.pi, 9.80665
FRAMES: list[tuple[str, dict[str, tuple[str, float]]]] = [
    ("WHEELS_F", {"WhlSpd_FL": ("omega_fl", RPM), "WhlSpd_FR": ("omega_fr", RPM)}),
    ("WHEELS_R", {"WhlSpd_RL": ("omega_rl", RPM), "WhlSpd_RR": ("omega_rr", RPM)}),
    ("TORQUES", {"Trq_FL": ("torque_fl", 1.0), "Trq_FR": ("torque_fr", 1.0)}),  # mux 0
    ("TORQUES", {"Trq_RL": ("torque_rl", 1.0), "Trq_RR": ("torque_rr", 1.0)}),  # mux 1
    ("IMU_ACC_XY", {"LongAccel": ("ax", 1 / G), "LatAccel": ("ay", 1 / G)}),
    ("IMU_ACC_Z", {"VertAccel": ("az", 1 / G)}),
    ("IMU_RATES_A", {"YawRateCW": ("yaw_rate", -DEG), "RollRate": ("roll_rate", DEG)}),
    ("IMU_RATES_B", {"PitchRate": ("pitch_rate", DEG)}),
    ("STEER", {"SteeringWheelAngle": ("steering_wheel_angle", DEG)}),
    ("ROAD_WHEEL", {"RoadWheelAngle_FL": ("delta_fl", DEG), "RoadWheelAngle_FR": ("delta_fr", DEG)}),
]
"""CAN message → {signal: (log column, DBC value per SI value)}; the yaw rate is clockwise."""

CAN_MAP = """format = 1
[source]
kind = "mdf"
dbc = "car.dbc"
[output]
rate = 200.0
max_gap = 0.1
[channels.omega_fl]
source = "WHEELS_F.WhlSpd_FL"
unit = "rpm"                       # the DBC's bare 1/min counts revolutions
[channels.omega_fr]
source = "WHEELS_F.WhlSpd_FR"
unit = "rpm"
[channels.omega_rl]
source = "WHEELS_R.WhlSpd_RL"
unit = "rpm"
[channels.omega_rr]
source = "WHEELS_R.WhlSpd_RR"
unit = "rpm"
[channels.yaw_rate]
source = "IMU_RATES_A.YawRateCW"
expr = "-src"                      # clockwise on the bus, counter-clockwise in ISO 8855
unit = "deg/s"
""" + "".join(f'[channels.{c}]\nsource = "{m}.{s}"\n' for m, sig in FRAMES for s, (c, _) in sig.items()
              if not c.startswith("omega") and c != "yaw_rate")
"""Every other entry takes its unit from the DBC (Nm, g, dps, deg)."""

ROS_MAP = """format = 1
[source]
kind = "ros2"
[output]
rate = 200.0
max_gap = 0.1
""" + "".join(f'[channels.{c}]\nsource = "{a}"\n' for c, a in {
    "ax": "/imu:linear_acceleration.x", "ay": "/imu:linear_acceleration.y",
    "az": "/imu:linear_acceleration.z", "roll_rate": "/imu:angular_velocity.x",
    "pitch_rate": "/imu:angular_velocity.y", "yaw_rate": "/imu:angular_velocity.z"}.items()) + "".join(
    f'[channels.{c}]\nsource = "{a}"\nunit = "{u}"\n' for c, a, u in [
        *((f"omega_{k}", f"/wheel_speeds:data[{i}]", "rad/s")
          for i, k in enumerate(("fl", "fr", "rl", "rr"))),
        *((f"torque_{k}", f"/wheel_torques:{k}", "N*m") for k in ("fl", "fr", "rl", "rr")),
        ("steering_wheel_angle", "/steering:steering_wheel_angle", "rad"),
        ("delta_fl", "/road_wheel_angles:fl", "rad"), ("delta_fr", "/road_wheel_angles:fr", "rad")])
"""sensor_msgs/Imu fields carry their REP-103 units; the other messages' fields are given."""


def write_can_mf4(log: pd.DataFrame, path: Path, dbc: Path) -> None:
    """``log`` as CAN frames: values encoded by cantools, frames written by python-can's MF4Writer."""
    db = cantools.database.load_file(str(dbc))
    writer = can.MF4Writer(str(path), database=str(dbc))
    try:
        t0 = writer._start_time  # MF4Writer stores times relative to its start: send absolute ones
        columns = {c: log[c].to_numpy() for _, sig in FRAMES for c, _ in sig.values()}
        for i, t in enumerate(log["t"].to_numpy()):
            for mux, (name, signals) in enumerate(FRAMES):
                message = db.get_message_by_name(name)
                values: dict[str, float] = {s: float(columns[c][i] * k) for s, (c, k) in signals.items()}
                if name == "TORQUES":
                    values["TrqMux"] = mux - 2
                data = message.encode(values, scaling=True, strict=True)
                writer.on_message_received(can.Message(
                    timestamp=t0 + float(t), arbitration_id=message.frame_id, is_extended_id=False,
                    data=data, channel=1))
    finally:
        writer.stop()


def _assert_decoded_as_asammdf(mf4: Path, dbc: Path) -> None:
    import asammdf

    from vestim.io.readers.mdf import read_streams

    addresses = [f"{m}.{s}" for m, sig in FRAMES for s in sig]
    ours = read_streams(mf4, addresses, dbc=[dbc])
    with asammdf.MDF(str(mf4)) as raw:
        decoded = raw.extract_bus_logging({"CAN": [(str(dbc), 0)]})
        try:
            for a in addresses:
                theirs = decoded.get(f"CAN1.{a}")
                np.testing.assert_array_equal(ours[a].value, np.asarray(theirs.samples, dtype=np.float64), a)
                np.testing.assert_array_equal(ours[a].t, theirs.timestamps, a)
                assert ours[a].unit == theirs.unit, a
        finally:
            decoded.close()


def _estimates(folder: Path) -> dict[str, pd.DataFrame]:
    return {p.name.removesuffix("_estimate.parquet"): pd.read_parquet(p)
            for p in sorted(folder.glob("*_estimate.parquet"))}


def test_raw_folder_channels_import_and_batch_give_the_parquet_estimates(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two simulated logs (step_steer, seeds 0 and 1, first 4 s) → two MDF4 + CAN files and two
    ROS 2 bags → ``vestim batch --map`` (one map per kind) → four estimates, each within
    0.01 σ (the median sigma_ of the Parquet estimate) of the estimate of its Parquet log on
    every channel with a sigma_. The CAN quantisation (1e-4 rpm, 1e-6 g, 1e-5 °/s) is below
    1e-4 of the sensor noise and float64 bag values are exact, so the differences come from
    float rounding and the CAN clock's 2.4e-7 s resolution (MF4Writer times relative to a
    POSIX start time); 0.01 σ is the bound the existing ingestion tests use."""
    from vestim.io.writers import write_ros2_bag

    monkeypatch.setenv("COLUMNS", "200")
    runner = CliRunner()
    sim, raw = tmp_path / "sim", tmp_path / "raw"
    sim.mkdir()
    raw.mkdir()
    for seed, stem in ((0, "drive_a"), (1, "drive_b")):
        full = tmp_path / f"{stem}_full.parquet"
        r = runner.invoke(app, ["simulate", "step_steer", "--out", str(full), "--seed", str(seed)])
        assert r.exit_code == 0, r.output
        log = pd.read_parquet(full)
        log = log[log["t"] <= SECONDS + 1e-9].reset_index(drop=True)
        log.to_parquet(sim / f"{stem}.parquet")
        (raw / "car.dbc").write_text(DBC)
        write_can_mf4(log, raw / f"{stem}_can.mf4", raw / "car.dbc")
        measured = log[[c for c in log.columns if not c.startswith("ref_")]]
        write_ros2_bag(measured, raw / f"{stem}_bag")
    (raw / "can.toml").write_text(CAN_MAP)
    (raw / "ros.toml").write_text(ROS_MAP)

    # The file is decoded as asammdf's extract_bus_logging decodes it, bit for bit, including
    # the multiplexed torques and the 32-bit Motorola signals of MF4Writer's 64-byte frames.
    _assert_decoded_as_asammdf(raw / "drive_a_can.mf4", raw / "car.dbc")

    # vestim channels: every signal with its DBC unit and rate; the starter map takes the DBC units.
    r = runner.invoke(app, ["channels", str(raw / "drive_a_can.mf4"), "--dbc", str(raw / "car.dbc")])
    assert r.exit_code == 0, r.output
    for address, unit in (("WHEELS_F.WhlSpd_FL", "1/min"), ("TORQUES.Trq_RR", "Nm"),
                          ("IMU_ACC_XY.LongAccel", "g"), ("IMU_RATES_A.YawRateCW", "dps")):
        line = next(ln for ln in r.output.splitlines() if address in ln)
        assert unit in line and " 200 " in line and " 801 " in line, line  # 801 samples at 200 Hz
    r = runner.invoke(app, ["channels", str(raw / "drive_a_bag")])
    assert r.exit_code == 0, r.output
    assert "/imu:linear_acceleration.x" in r.output and "m/s^2" in r.output
    r = runner.invoke(app, ["channels", str(raw / "drive_a_can.mf4"), "--dbc", str(raw / "car.dbc"),
                            "--starter-map"])
    assert r.exit_code == 0, r.output
    starter = tomllib.loads(r.output)["channels"]
    assert len(starter) == 17  # every measured channel of the bus recognised by name and unit
    assert starter["torque_rl"] == {"source": "TORQUES.Trq_RL"}  # unit Nm from the DBC
    assert starter["omega_fl"]["unit"] == "rpm"  # the DBC's 1/min made explicit, to check

    # vestim import: the log back, to half the DBC's step (1e-4 rpm, 1e-6 g, 1e-5 °/s, 1e-6°)
    # plus the clock's resolution: MF4Writer's times are POSIX times less its start, so each
    # is off by up to one float64 step at 1.8e9 s (2.4e-7 s), which moves a value by up to
    # 2.4e-7 s × 200 Hz × the largest change between two samples.
    imported = tmp_path / "drive_a_imported.parquet"
    r = runner.invoke(app, ["import", str(raw / "drive_a_can.mf4"), "--map", str(raw / "can.toml"),
                            "--out", str(imported)])
    assert r.exit_code == 0, r.output
    back, original = pd.read_parquet(imported), pd.read_parquet(sim / "drive_a.parquet")
    units = json.loads(read_log(imported).attrs["import.units"])  # what each channel was read in
    assert units["omega_fl"] == "rpm" and units["yaw_rate"] == "deg/s"
    assert units["torque_fl"] == "Nm (source)" and units["ax"] == "g (source)"
    assert len(back) == len(original) == 801
    steps = {"omega_fl": 1e-4 / RPM, "torque_rr": 1e-4, "ax": 1e-6 * G, "yaw_rate": 1e-5 / DEG,
             "delta_fr": 1e-6 / DEG}
    for c, step in steps.items():
        jump = float(np.abs(np.diff(original[c])).max())
        np.testing.assert_allclose(back[c], original[c], rtol=0, atol=step / 2 + 2.4e-7 * 200 * jump,
                                   err_msg=c)

    # vestim batch: the Parquet route, then the raw folder through the two maps.
    common = ["--vehicle", "hashemi_suv", "--scheduler", "synchronous"]
    r = runner.invoke(app, ["batch", str(sim), "--out", str(tmp_path / "est_parquet"), *common])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["batch", str(raw), "--map", str(raw / "can.toml"), "--map", str(raw / "ros.toml"),
                            "--out", str(tmp_path / "est_raw"), *common])
    assert r.exit_code == 0, r.output
    assert "4 logs: 4 ok" in r.output
    parquet, from_raw = _estimates(tmp_path / "est_parquet"), _estimates(tmp_path / "est_raw")
    assert sorted(from_raw) == ["drive_a_bag", "drive_a_can", "drive_b_bag", "drive_b_can"]
    for name, est in from_raw.items():
        ref = parquet[name.rsplit("_", 1)[0]]
        assert len(est) == len(ref)
        checked = 0
        for c in [c for c in ref.columns if f"sigma_{c}" in ref.columns and not c.startswith("mu_")]:
            sigma = float(ref[f"sigma_{c}"].median())
            worst = float(np.nanmax(np.abs(est[c].to_numpy() - ref[c].to_numpy())))
            assert worst < 0.01 * sigma, f"{name} {c}: {worst:.3g} vs sigma {sigma:.3g}"
            checked += 1
        assert checked >= 10, name
