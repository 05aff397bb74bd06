"""MDF4 reader (vestim.io.readers.mdf) and the MDF4/CAN writer (vestim.io.writers).

Round trips use the real libraries: the log is encoded into CAN frames, written with asammdf
as an ASAM bus-logging group, read back and decoded with the DBC. Each value comes back
within half its DBC factor (the writer rounds to the nearest step), and the decoding agrees
with two independent decoders, cantools' own ``decode_message`` and asammdf's
``extract_bus_logging`` (which uses canmatrix).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests._paths import CROSSPLANT_DATA
from vestim.errors import LogFormatError, VestimError
from vestim.io.readers import mdf
from vestim.io.writers import (
    CAN_SIGNALS,
    VEHICLE_DBC,
    can_database,
    can_frames,
    check_can_values,
    write_mdf_can,
)

asammdf = pytest.importorskip("asammdf")
cantools = pytest.importorskip("cantools")

CROSSPLANT = CROSSPLANT_DATA
X05 = CROSSPLANT / "x05_sine_steer_dry_rwd.parquet"
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "mdf4_can"
needs_crossplant = pytest.mark.skipif(not X05.exists(), reason="crossplant logs not available")


def _measured(path: Path, seconds: float) -> pd.DataFrame:
    df = pd.read_parquet(path)
    df = df.loc[df["t"] <= seconds + 1e-9, [c for c in df.columns if not c.startswith("ref_")]]
    return df.reset_index(drop=True)


@pytest.fixture(scope="module")
def log() -> pd.DataFrame:
    """The first 10 s of crossplant x05 (sine steer, 200 Hz, 2001 rows), measured channels."""
    if not X05.exists():
        pytest.skip("crossplant logs not available")
    return _measured(X05, 10.0)


@pytest.fixture(scope="module")
def container(log: pd.DataFrame, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("mdf")
    mf4, dbc = folder / "x05.mf4", folder / "vehicle.dbc"
    write_mdf_can(log, mf4, dbc)
    return mf4, dbc


def _step_si(column: str) -> float:
    """DBC factor of the column's signal in SI units: the quantisation step."""
    target = CAN_SIGNALS[column]
    message, signal = target.address.split(".")
    return float(can_database().get_message_by_name(message).get_signal_by_name(signal).scale) / target.per_si


# --- round trip -----------------------------------------------------------------------------


def test_round_trip_within_half_a_dbc_step(log: pd.DataFrame, container: tuple[Path, Path]) -> None:
    """Every signal is back within factor/2 of the log (rounding to the nearest step), at the log's t.

    E.g. wheel speed 0.05 rpm per bit → ≤ 0.00262 rad/s; yaw rate 0.01 °/s → ≤ 8.7e-5 rad/s;
    accelerations 0.002 m/s² → ≤ 0.001 m/s²; torques 0.5 N·m → ≤ 0.25 N·m. The bound is also
    reached: the largest error is more than 0.9 × factor/2 (2001 samples of a uniform error).
    """
    mf4, dbc = container
    columns = [c for c in CAN_SIGNALS if c in log.columns]
    assert len(columns) == 17
    streams = mdf.read_streams(mf4, [CAN_SIGNALS[c].address for c in columns], dbc=[dbc])
    for c in columns:
        s = streams[CAN_SIGNALS[c].address]
        np.testing.assert_array_equal(s.t, log["t"].to_numpy())
        err = np.abs(s.value / CAN_SIGNALS[c].per_si - log[c].to_numpy())
        half = _step_si(c) / 2
        assert err.max() <= half * (1 + 1e-9), c
        assert err.max() > 0.9 * half, c


def test_decoding_agrees_with_cantools_and_asammdf(container: tuple[Path, Path]) -> None:
    """Our NumPy decoding equals cantools' decode_message frame by frame (to 1e-9: cantools
    scales in Python floats, possibly in another order), and asammdf's own bus-logging
    extraction (canmatrix) channel by channel bit for bit, values and times: vestim keeps its
    decoder, 5-6x faster than extract_bus_logging (benchmarks/bench_mdf_read.py), only
    because it gives the library's samples exactly."""
    mf4, dbc = container
    db = can_database()
    addresses = [f"{m.name}.{s.name}" for m in db.messages if m.name != "GNSS_SPEED" for s in m.signals]
    ours = mdf.read_streams(mf4, addresses, dbc=[dbc])
    with asammdf.MDF(str(mf4)) as raw:
        ids = raw.get("CAN_DataFrame.ID").samples & 0x1FFFFFFF
        data = raw.get("CAN_DataFrame.DataBytes").samples
        decoded = raw.extract_bus_logging({"CAN": [(str(dbc), 0)]})
    for message in db.messages:
        if message.name == "GNSS_SPEED":
            continue
        rows = np.flatnonzero(ids == message.frame_id)
        ref = [db.decode_message(message.frame_id, bytes(data[i]), decode_choices=False) for i in rows]
        for signal in message.signals:
            address = f"{message.name}.{signal.name}"
            np.testing.assert_allclose(ours[address].value, [r[signal.name] for r in ref], rtol=0, atol=1e-9)
            other = decoded.get(f"CAN1.{address}")
            np.testing.assert_array_equal(ours[address].value, np.asarray(other.samples, dtype=np.float64))
            np.testing.assert_array_equal(ours[address].t, other.timestamps)
            assert ours[address].unit == (other.unit or None)  # the DBC's unit, as asammdf gives it
    decoded.close()


def test_frames_decode_back_with_cantools(log: pd.DataFrame) -> None:
    """The writer's frames (encoded by cantools) decode with cantools' decode_message to the
    log's values within half a DBC step, six messages per row."""
    db = can_database()
    t, ids, payload = can_frames(log.iloc[:200])
    assert len(t) == 200 * 6  # six messages per row (no gnss_speed in x05)
    by_address = {s.address: (c, s.per_si) for c, s in CAN_SIGNALS.items()}
    for i in range(len(t)):
        frame_id = int(ids[i]) & 0x1FFFFFFF
        message = db.get_message_by_frame_id(frame_id)
        values = db.decode_message(frame_id, bytes(payload[i][: message.length]), decode_choices=False)
        row = int(np.searchsorted(log["t"].to_numpy(), t[i]))
        for name, value in values.items():
            column, per_si = by_address[f"{message.name}.{name}"]
            assert abs(value / per_si - log[column].iloc[row]) <= _step_si(column) / 2 * (1 + 1e-9)


def test_the_example_dbc_is_the_writers() -> None:
    """examples/mdf4_can/vehicle.dbc (committed) is VEHICLE_DBC, so the example map decodes it."""
    assert (EXAMPLE / "vehicle.dbc").read_text(encoding="utf-8") == VEHICLE_DBC


# --- decoding of DBC layouts (property tests against cantools) --------------------------------


@st.composite
def _layout(draw: st.DrawFn) -> tuple[str, int, int, bool]:
    """(byte order, DBC start bit, length, signed) of a signal that fits an 8-byte frame."""
    order = draw(st.sampled_from(["little_endian", "big_endian"]))
    length = draw(st.integers(1, 64))
    signed = draw(st.booleans()) and length > 1
    if order == "little_endian":
        start = draw(st.integers(0, 64 - length))
    else:  # Motorola: the MSB at start, bits run towards the LSB of the last byte
        msb_pos = draw(st.integers(length - 1, 63))  # position in the big-endian 64-bit word
        start = (7 - msb_pos // 8) * 8 + msb_pos % 8
    return order, start, length, signed


@settings(max_examples=60, deadline=None)
@given(layout=_layout(), seed=st.integers(0, 2**32 - 1), fd=st.booleans())
def test_decode_signal_matches_cantools(layout: tuple[str, int, int, bool], seed: int, fd: bool) -> None:
    """Any Intel/Motorola, signed/unsigned field of 1–64 bits decodes as cantools decodes it,
    on 8-byte frames (64-bit word path) and inside 64-byte CAN FD frames (byte-wise path),
    with random payload bytes: exactly equal raw values, so the values agree to 1e-12."""
    order, start, length, signed = layout
    n_bytes = 64 if fd else 8
    if fd:
        start += 8 * 40  # move the field into bytes 40..48 of the FD frame
    signal = cantools.database.can.Signal(
        "S", start, length, byte_order=order, is_signed=signed,
        conversion=cantools.database.conversion.BaseConversion.factory(scale=0.5, offset=-3.0))
    message = cantools.database.can.Message(0x123, "M", n_bytes, [signal], is_fd=fd, strict=False)
    payload = np.random.default_rng(seed).integers(0, 256, size=(16, n_bytes), dtype=np.uint8)
    ref = [message.decode(bytes(p), decode_choices=False)["S"] for p in payload]
    np.testing.assert_allclose(mdf.decode_signal(payload, signal), ref, rtol=1e-12, atol=1e-12)
    words = mdf._Words.of(payload)
    assert (words is None) == fd
    if words is not None:
        np.testing.assert_allclose(mdf.decode_signal(words, signal), ref, rtol=1e-12, atol=1e-12)


def test_float_and_multiplexed_signals() -> None:
    """IEEE float32 signals decode to their value; a multiplexed signal appears only in the
    frames whose multiplexer selects it (here 3 of 6 frames each)."""
    db = cantools.database.load_string(
        'VERSION ""\n\nBO_ 100 MUXED: 8 X\n'
        " SG_ Mux M : 0|8@1+ (1,0) [0|255] \"\" X\n"
        " SG_ A m0 : 8|16@1- (0.1,0) [-3276.8|3276.7] \"\" X\n"
        " SG_ B m1 : 8|32@1- (1,0) [0|0] \"\" X\n\n"
        'BO_ 101 FLOATS: 8 X\n SG_ F : 0|32@1- (1,0) [0|0] "" X\n\n'
        "SIG_VALTYPE_ 101 F : 1;\nSIG_VALTYPE_ 100 B : 1;\n", database_format="dbc")
    muxed, floats = db.get_message_by_name("MUXED"), db.get_message_by_name("FLOATS")
    frames = [muxed.encode({"Mux": 0, "A": 1.5 * k} if k % 2 == 0 else {"Mux": 1, "B": 0.25 * k})
              for k in range(6)]
    payload = np.array([np.frombuffer(f.ljust(8, b"\0"), dtype=np.uint8) for f in frames])
    for name, expected in (("A", [0.0, 3.0, 6.0]), ("B", [0.25, 0.75, 1.25])):
        signal = muxed.get_signal_by_name(name)
        mask = mdf._mux_mask(payload, muxed, signal)
        assert mask is not None and mask.sum() == 3
        np.testing.assert_allclose(mdf.decode_signal(payload, signal)[mask], expected, rtol=0, atol=1e-12)
    f = np.frombuffer(floats.encode({"F": -1.234e-3}), dtype=np.uint8)[None, :]
    assert mdf.decode_signal(f, floats.get_signal_by_name("F"))[0] == np.float32(-1.234e-3)


# --- plain channels and addresses -------------------------------------------------------------


@pytest.fixture(scope="module")
def plain_mdf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two groups with a channel 'speed' (acq names ESP, GPS) and one with 'temp' whose samples
    2 and 3 are flagged invalid."""
    path = tmp_path_factory.mktemp("plain") / "plain.mf4"
    t = np.arange(10) * 0.1
    out = asammdf.MDF(version="4.10")
    out.append([asammdf.Signal(np.arange(10.0), t, name="speed", unit="km/h")], acq_name="ESP")
    out.append([asammdf.Signal(np.arange(10.0) * 2, t + 0.05, name="speed", unit="km/h")], acq_name="GPS")
    invalid = np.zeros(10, dtype=bool)
    invalid[[2, 3]] = True
    out.append([asammdf.Signal(np.arange(10, dtype=np.int16), t, name="temp", invalidation_bits=invalid),
                asammdf.Signal(np.array([b"a"] * 10), t, name="label", encoding="utf-8")], acq_name="misc")
    out.save(path, overwrite=True)
    out.close()
    return path


def test_plain_channels_group_qualifier_and_invalid_samples(plain_mdf: Path) -> None:
    """GROUP/name picks one of two 'speed' channels by acquisition name or group index; invalid
    samples are dropped (8 of 10 remain), not filled."""
    s = mdf.read_streams(plain_mdf, ["ESP/speed", "1/speed", "temp"])
    np.testing.assert_array_equal(s["ESP/speed"].value, np.arange(10.0))
    np.testing.assert_array_equal(s["1/speed"].value, np.arange(10.0) * 2)
    np.testing.assert_allclose(s["1/speed"].t, np.arange(10) * 0.1 + 0.05)
    np.testing.assert_array_equal(s["temp"].value, [0, 1, 4, 5, 6, 7, 8, 9])
    np.testing.assert_allclose(s["temp"].t, np.array([0, 1, 4, 5, 6, 7, 8, 9]) * 0.1)


def test_channel_listing_of_plain_channels(plain_mdf: Path) -> None:
    """`vestim channels`: the two 'speed' channels as GROUP/speed with their MDF unit, 'temp'
    with its 8 valid samples at 10 Hz; the text channel is not listed."""
    from vestim.io.listing import list_signals

    listing = list_signals(plain_mdf)
    got = {s.address: (s.unit, s.samples, round(s.rate_hz, 6)) for s in listing.signals}
    assert got == {"0/speed": ("km/h", 10, 10.0), "1/speed": ("km/h", 10, 10.0), "temp": (None, 8, 10.0)}


def test_ambiguous_channel_lists_the_groups(plain_mdf: Path) -> None:
    with pytest.raises(LogFormatError,
                       match=r"'speed' is in 2 channel groups.*0/speed \(ESP\).*1/speed \(GPS\)"):
        mdf.read_streams(plain_mdf, ["speed"])
    with pytest.raises(LogFormatError, match="no channel group 'ABS' holds channel 'speed'"):
        mdf.read_streams(plain_mdf, ["ABS/speed"])


def test_missing_channel_names_close_matches(plain_mdf: Path) -> None:
    with pytest.raises(LogFormatError, match=r"no channel 'tmp' in the file; close matches: temp"):
        mdf.read_streams(plain_mdf, ["tmp"])


def test_text_channel_is_refused(plain_mdf: Path) -> None:
    with pytest.raises(LogFormatError, match="'label' holds text values"):
        mdf.read_streams(plain_mdf, ["label"])


# --- CAN errors -------------------------------------------------------------------------------


def test_signal_not_in_dbc(container: tuple[Path, Path]) -> None:
    mf4, dbc = container
    with pytest.raises(LogFormatError, match=r"message 'WHEEL_SPEEDS' .* has no signal 'WheelSpeed_FX'.*"
                                             r"close matches: WheelSpeed_F"):
        mdf.read_streams(mf4, ["WHEEL_SPEEDS.WheelSpeed_FX"], dbc=[dbc])
    with pytest.raises(LogFormatError, match=r"no channel 'WHEEL_SPEED.WheelSpeed_FL' .*nor message.signal "
                                             r"in the DBC; close matches: WHEEL_SPEEDS.WheelSpeed_FL"):
        mdf.read_streams(mf4, ["WHEEL_SPEED.WheelSpeed_FL"], dbc=[dbc])


def test_raw_frames_without_dbc_say_to_pass_one(container: tuple[Path, Path]) -> None:
    mf4, _ = container
    with pytest.raises(LogFormatError, match="has raw CAN frames: pass the bus's DBC file"):
        mdf.read_streams(mf4, ["WHEEL_SPEEDS.WheelSpeed_FL"])


def test_message_without_frames_and_bus_selection(container: tuple[Path, Path]) -> None:
    """x05 has no gnss_speed, so GNSS_SPEED (ID 0x18FEF1A0) has no frame; bus 1 holds the
    frames, bus 2 none."""
    mf4, dbc = container
    with pytest.raises(LogFormatError, match=r"no CAN frame with ID 0x18FEF1A0 \(message 'GNSS_SPEED'"):
        mdf.read_streams(mf4, ["GNSS_SPEED.SpeedOverGround"], dbc=[dbc])
    one = mdf.read_streams(mf4, ["CAN1.IMU_RATES.YawRate", "IMU_RATES.YawRate"], dbc=[dbc])
    np.testing.assert_array_equal(one["CAN1.IMU_RATES.YawRate"].value, one["IMU_RATES.YawRate"].value)
    with pytest.raises(LogFormatError, match="on bus 2"):
        mdf.read_streams(mf4, ["CAN2.IMU_RATES.YawRate"], dbc=[dbc])


def test_frames_shorter_than_the_dbc_message(container: tuple[Path, Path], tmp_path: Path) -> None:
    """A DBC whose WHEEL_SPEEDS is 10 bytes long does not match 8-byte frames: named error."""
    mf4, _ = container
    wrong = tmp_path / "wrong.dbc"
    wrong.write_text(VEHICLE_DBC.replace("BO_ 416 WHEEL_SPEEDS: 8 ABS", "BO_ 416 WHEEL_SPEEDS: 10 ABS"))
    with pytest.raises(LogFormatError,
                       match=r"2001 of 2001 frames with ID 0x1A0 carry fewer than the 10 bytes"):
        mdf.read_streams(mf4, ["WHEEL_SPEEDS.WheelSpeed_FL"], dbc=[wrong])


def test_bad_files(tmp_path: Path, container: tuple[Path, Path]) -> None:
    mf4, _ = container
    garbage = tmp_path / "garbage.mf4"
    garbage.write_bytes(b"not an MDF file at all" * 10)
    with pytest.raises(LogFormatError, match="is not a readable MDF file"):
        mdf.read_streams(garbage, ["x"])
    with pytest.raises(LogFormatError, match="does not exist"):
        mdf.read_streams(tmp_path / "missing.mf4", ["x"])
    with pytest.raises(LogFormatError, match=r"DBC file .*missing\.dbc does not exist"):
        mdf.read_streams(mf4, ["x"], dbc=[tmp_path / "missing.dbc"])
    bad_dbc = tmp_path / "bad.dbc"
    bad_dbc.write_text("BO_ this is not a dbc")
    with pytest.raises(LogFormatError, match="is not a readable DBC"):
        mdf.read_streams(mf4, ["x"], dbc=[bad_dbc])


def test_missing_optional_package_says_how_to_install() -> None:
    """The import guard (the same one asammdf and cantools go through) names the package and
    the extra; a package that is not installed stands in for a missing asammdf."""
    with pytest.raises(VestimError,
                       match=r"'vestim_no_such_package', which is not installed.*vestim\[logs\]"):
        mdf._optional("vestim_no_such_package", "reading MDF4 files")


# --- writer errors ----------------------------------------------------------------------------


def test_writer_refuses_out_of_range_and_partial_messages(log: pd.DataFrame, tmp_path: Path) -> None:
    """3500 rpm does not fit WheelSpeed_FL (16 bits × 0.05 rpm = 3276.75 rpm); NaN is not
    sendable; a log with ax but no az cannot fill IMU_ACCEL. Nothing is written."""
    fast = log.copy()
    fast.loc[7, "omega_fl"] = 3500 * 2 * np.pi / 60  # rad/s
    with pytest.raises(LogFormatError, match=r"column 'omega_fl' row 7: 3500 rpm is outside the range"):
        write_mdf_can(fast, tmp_path / "a.mf4")
    gap = log.copy()
    gap.loc[3, "ay"] = np.nan
    with pytest.raises(LogFormatError, match=r"column 'ay' row 3: nan cannot be sent"):
        write_mdf_can(gap, tmp_path / "b.mf4")
    with pytest.raises(LogFormatError, match=r"has 'ax' but not 'az'"):
        write_mdf_can(log.drop(columns=["az"]), tmp_path / "c.mf4")
    with pytest.raises(LogFormatError, match="none of the channels the CAN bus carries"):
        write_mdf_can(log[["t"]], tmp_path / "d.mf4")
    assert not list(tmp_path.iterdir())
    signal = can_database().get_message_by_name("IMU_RATES").get_signal_by_name("YawRate")
    with pytest.raises(LogFormatError, match="'yaw' row 0"):
        check_can_values(np.array([400.0]), signal, column="yaw")


# --- the estimate through the channel map (issue 14) ------------------------------------------


@needs_crossplant
def test_mdf_import_gives_the_parquet_estimate(log: pd.DataFrame, container: tuple[Path, Path]) -> None:
    """x05 through MDF4 + CAN + DBC and examples/mdf4_can/map.toml gives the Parquet estimate.

    1. The imported log is the Parquet log rounded to the DBC steps (to 1e-12 after pint's unit
       conversions), so Pipeline.run on it equals Pipeline.run on the rounded Parquet log to
       float rounding (1e-9 relative to each output's scale).
    2. Against the unrounded Parquet log the difference is the quantisation's: each DBC step's
       noise (step/√12) is ≤ 1/10 of the log's sensor noise on every channel (manifest: accel
       0.07 m/s² vs 0.0006, gyro 0.005 rad/s vs 5e-5, ω 0.06 rad/s vs 0.0015, δ 1e-4 rad vs
       1e-5, torque 20 N·m vs 0.14), so the estimate moves by < 0.1 of its own one-sigma
       (median sigma_vx, sigma_vy, sigma_fx_*, sigma_fy_*). Measured: v_y 0.056 σ (0.82 mm/s),
       v_x 0.010 σ, F_y ≤ 0.045 σ.
    """
    from vestim.io import load_vehicle
    from vestim.io.channel_map import import_log
    from vestim.pipeline import Pipeline, PipelineConfig

    mf4, _ = container
    imported, _ = import_log(mf4, EXAMPLE / "map.toml")
    assert len(imported) == len(log)
    db = can_database()
    rounded = log.copy()
    for c in imported.columns.drop("t"):
        target = CAN_SIGNALS[c]
        message, name = target.address.split(".")
        sig = db.get_message_by_name(message).get_signal_by_name(name)
        raw = np.rint((log[c].to_numpy() * target.per_si - sig.offset) / sig.scale)
        rounded[c] = (raw * sig.scale + sig.offset) / target.per_si
        np.testing.assert_allclose(imported[c], rounded[c], rtol=1e-12, atol=1e-12, err_msg=c)
    vehicle = load_vehicle(CROSSPLANT / "vehicle2.toml")
    est = {k: Pipeline(vehicle, PipelineConfig()).run(v) for k, v in
           (("parquet", log), ("rounded", rounded), ("mdf", imported))}
    for c in est["mdf"].columns.drop("t"):
        a, b = est["mdf"][c].to_numpy(), est["rounded"][c].to_numpy()
        finite = np.abs(b[np.isfinite(b)])  # friction is NaN (unknown) where not excited
        scale = max(float(finite.max()) if finite.size else 0.0, 1e-12)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * scale, err_msg=c)
    for c in [c for c in est["mdf"].columns if f"sigma_{c}" in est["mdf"].columns]:
        sigma = float(est["parquet"][f"sigma_{c}"].median())
        if c.startswith("mu_"):  # friction: NaN where not excited, compared above exactly
            continue
        worst = float(np.max(np.abs(est["mdf"][c] - est["parquet"][c])))
        assert worst < 0.1 * sigma, f"{c}: {worst:.3g} vs sigma {sigma:.3g}"


FD_DBC = """VERSION ""

BO_ 512 CLASSIC: 8 X
 SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] "m/s" X

BO_ 513 FD_BLOCK: 64 X
 SG_ Far : 480|16@1- (0.1,0) [-3276.8|3276.7] "" X
 SG_ FarBig : 407|12@0- (1,0) [-2048|2047] "" X
"""


def _bus_group(frames: list[tuple[float, int, bytes]], bus: int, width: int) -> Any:
    from asammdf.blocks import v4_constants as v4c
    from asammdf.blocks.source_utils import Source

    dtype = np.dtype([("CAN_DataFrame.BusChannel", "u1"), ("CAN_DataFrame.ID", "<u4"),
                      ("CAN_DataFrame.DataLength", "u1"), ("CAN_DataFrame.DataBytes", "u1", (width,))])
    rec = np.zeros(len(frames), dtype=dtype)
    rec["CAN_DataFrame.BusChannel"] = bus
    rec["CAN_DataFrame.ID"] = [f[1] for f in frames]
    rec["CAN_DataFrame.DataLength"] = [len(f[2]) for f in frames]
    rec["CAN_DataFrame.DataBytes"] = [np.frombuffer(f[2].ljust(width, b"\0"), np.uint8) for f in frames]
    source = Source(name=f"CAN{bus}", path=f"CAN{bus}", comment="", source_type=v4c.SOURCE_BUS,
                    bus_type=v4c.BUS_TYPE_CAN)
    return asammdf.Signal(rec, np.array([f[0] for f in frames]), name="CAN_DataFrame", source=source)


def test_two_bus_groups_classic_and_fd(tmp_path: Path) -> None:
    """A classic 8-byte group (bus 1) and a CAN FD 64-byte group (bus 2), no IDE channel:
    frames of both are decoded (FD: Far in bytes 60–61, Intel; FarBig in bytes 50–51,
    Motorola), an extended flag is read from ID bit 31, CLASSIC is on both buses so needs
    CANn., and each stream comes back in time order although the two groups interleave."""
    db = cantools.database.load_string(FD_DBC, database_format="dbc")
    classic, fd = db.get_message_by_name("CLASSIC"), db.get_message_by_name("FD_BLOCK")
    bus1 = [(0.01 * k, 512, classic.encode({"Speed": 10.0 + k})) for k in range(5)]
    bus2 = ([(0.005 + 0.01 * k, 513, fd.encode({"Far": -1.5 * k, "FarBig": 7 - 3 * k})) for k in range(4)]
            + [(0.5, 512, classic.encode({"Speed": 99.0}))])
    path, dbc = tmp_path / "two.mf4", tmp_path / "fd.dbc"
    dbc.write_text(FD_DBC)
    out = asammdf.MDF(version="4.10")
    out.append([_bus_group(bus1, 1, 8)], acq_name="CAN1")
    out.append([_bus_group(bus2, 2, 64)], acq_name="CAN2")
    out.save(path, overwrite=True)
    out.close()
    wanted = ["FD_BLOCK.Far", "FD_BLOCK.FarBig", "CAN1.CLASSIC.Speed", "CAN2.CLASSIC.Speed"]
    s = mdf.read_streams(path, wanted, dbc=[dbc])
    np.testing.assert_allclose(s["FD_BLOCK.Far"].value, [0.0, -1.5, -3.0, -4.5], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(s["FD_BLOCK.FarBig"].value, [7, 4, 1, -2])
    np.testing.assert_allclose(s["FD_BLOCK.Far"].t, 0.005 + 0.01 * np.arange(4))
    np.testing.assert_allclose(s["CAN1.CLASSIC.Speed"].value, 10.0 + np.arange(5), rtol=0, atol=1e-12)
    np.testing.assert_allclose(s["CAN2.CLASSIC.Speed"].value, [99.0])
    with pytest.raises(LogFormatError, match=r"'CLASSIC' \(ID 0x200\) is on buses 1, 2; address one bus as "
                                             r"CAN1.CLASSIC.Speed"):
        mdf.read_streams(path, ["CLASSIC.Speed"], dbc=[dbc])


def test_one_delta_goes_as_both_road_wheel_angles(log: pd.DataFrame, tmp_path: Path) -> None:
    """A log with ``delta`` (one angle for both front wheels) instead of delta_fl/delta_fr is
    sent as both RoadWheelAngle signals (within the 0.002° step); the log is not modified."""
    one = log.drop(columns=["delta_fl", "delta_fr"]).assign(delta=log["delta_fl"])
    before = one.copy()
    mf4, dbc = tmp_path / "delta.mf4", tmp_path / "vehicle.dbc"
    write_mdf_can(one, mf4, dbc)
    pd.testing.assert_frame_equal(one, before)
    s = mdf.read_streams(mf4, ["ROAD_WHEEL_ANGLES.RoadWheelAngle_FL", "ROAD_WHEEL_ANGLES.RoadWheelAngle_FR"],
                         dbc=[dbc])
    for v in s.values():
        err = np.abs(np.radians(v.value) - one["delta"].to_numpy())
        assert err.max() <= _step_si("delta_fl") / 2 * (1 + 1e-9)
