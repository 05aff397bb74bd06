"""Command-line interface: ``vestim maneuvers | simulate | demo``.

Errors a user can fix (bad option, unknown maneuver, invalid vehicle file)
print one clear line and exit with status 2, never a traceback.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import rich.markup
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from vestim.errors import VestimError

if TYPE_CHECKING:
    from vestim.sim.maneuvers import Maneuver

# The commands import what they use: `vestim --help` and `--version` start in a fraction of a
# second instead of loading numba, pandas, scipy and matplotlib (about 1.6 s).

# rich_markup_mode=None: help text is printed as written; Rich markup would delete every
# bracketed word ("a [pipeline] table" read "a  table").
app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Corner-based vehicle state and tire-force estimation.")
console = Console(stderr=True, soft_wrap=True)  # messages stay one line (grep-able)


def _version(value: bool) -> None:
    if value:
        from vestim import __version__

        typer.echo(f"vestim {__version__}")
        raise typer.Exit()


def _say(text: str) -> None:
    console.print(rich.markup.escape(text))


@app.callback()
def _main(
    ctx: typer.Context,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
) -> None:
    """Corner-based vehicle state and tire-force estimation."""
    from vestim import _cache

    # Every command: a Numba compilation still running after 1 s says so (first run of a
    # code path on this machine); a run that loads its kernels from the cache is quiet.
    ctx.with_resource(_cache.compile_notice(_say))

BUILTINS = "hashemi_suv, compact_car"
"""The built-in vehicles' names (vestim.io.vehicle.BUILTIN_VEHICLES; written out here so that
`vestim --help` does not import the io layer)."""


class _MissingVehicle(typer.BadParameter):
    """A usage error (exit status 2) printed as written, not as "Invalid value for …"."""

    def format_message(self) -> str:
        return self.message


def _required_vehicle(value: str) -> str:
    """--vehicle has no default: a log estimated with another car's file is silently off (a
    4 % v_x error for hashemi_suv's file on a compact car's log, issue 30)."""
    if not value:
        raise _MissingVehicle(
            "Missing option '--vehicle': give the vehicle TOML file of the car the log was "
            f"recorded with, or a built-in vehicle by name (built-ins: {BUILTINS}), e.g. "
            "--vehicle car.toml or --vehicle compact_car")
    return value


VehicleOpt = Annotated[str, typer.Option(
    "--vehicle", callback=_required_vehicle, show_default=False,
    help=f"Vehicle TOML file or built-in name ({BUILTINS}); required.")]
"""A required --vehicle (its empty default is refused by the callback with the built-ins'
names; Typer's own "Missing option" would not name them)."""
SimVehicleOpt = Annotated[str, typer.Option("--vehicle", help="Vehicle to simulate: a TOML "
                                            f"file or built-in name ({BUILTINS}).")]


LOG_SUFFIXES = (".csv", ".parquet", ".pq")
PROGRESS_AFTER_S = 2.0
"""A run shows a progress bar once it has taken this long (shorter runs stay quiet)."""


class _Progress:
    """A Rich progress bar that appears only for runs longer than :data:`PROGRESS_AFTER_S`."""

    def __init__(self, label: str) -> None:
        self._label = label
        self._t0 = time.perf_counter()
        self._bar: Progress | None = None
        self._task: Any = None

    def __call__(self, fraction: float) -> None:
        if self._bar is None:
            if time.perf_counter() - self._t0 < PROGRESS_AFTER_S or not console.is_terminal:
                return
            self._bar = Progress(TextColumn("{task.description}"), BarColumn(),
                                 TextColumn("{task.percentage:>3.0f} %"), TimeElapsedColumn(),
                                 console=console, transient=True)
            self._bar.start()
            self._task = self._bar.add_task(self._label, total=1.0)
        self._bar.update(self._task, completed=fraction)

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


def _fail(exc: Exception) -> typer.Exit:
    # escape: a message naming an extra ("vestim[report]") is not Rich markup
    console.print(f"[red]error:[/red] {rich.markup.escape(str(exc))}")
    return typer.Exit(code=2)


def _run(m: Maneuver, vehicle: str, seed: int, rate: float, label: str,  # type: ignore[no-untyped-def]
         sensors: str = "default", roll_scale: float = 1.0):
    """Simulate with a progress bar on the terminal (hidden when not interactive)."""
    from vestim.io import load_vehicle
    from vestim.sim import SensorModel, simulate

    if sensors not in ("default", "realistic"):
        raise ValueError(f"--sensors {sensors!r}: use default or realistic")
    veh = load_vehicle(vehicle)
    model = SensorModel.realistic(rate) if sensors == "realistic" else SensorModel(rate=rate)
    with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as bar:
        task = bar.add_task(label, total=1.0)
        log = simulate(m, veh, seed=seed, sensors=model, roll_scale=roll_scale,
                       progress=lambda f: bar.update(task, completed=f))
    return veh, log


@app.command("maneuvers")
def maneuvers_cmd() -> None:
    """List the maneuver library, one per line, name first."""
    from vestim.sim import maneuver_names
    from vestim.sim.maneuvers import describe

    for name in maneuver_names():
        typer.echo(f"{name}\t{describe(name)}")


@app.command("methods")
def methods_cmd(
    stage: Annotated[str | None, typer.Argument(help="force | normal | velocity | fusion "
                                                "(default: every stage).")] = None,
) -> None:
    """List the registered estimation methods: stage, name, what it does, its paper equations
    and the [pipeline.<table>] TOML tables that set its parameters; the default is starred."""
    from vestim.estimators import registry

    try:
        stages = registry.STAGES if stage is None else (registry.lookup_stage(stage),)
        for st in stages:
            for m in registry.methods(st):
                cite = m.cite or "ours"
                tables = ", ".join(f"[pipeline.{t}]" for t in m.tables) or "-"
                typer.echo(f"{st}\t{m.name}{'*' if m.default else ''}\t{m.summary}\t{cite}\t"
                           f"{tables}")
    except VestimError as exc:
        raise _fail(exc) from None


@app.command("config")
def config_cmd(
    config: Annotated[Path | None, typer.Argument(help="A TOML file with a [pipeline] table to "
                                                  "check and print in full (default: the "
                                                  "defaults).")] = None,
) -> None:
    """Print a pipeline configuration as TOML, every parameter written out: the defaults, or
    CONFIG checked and completed with them. Edit the output and pass it to
    `vestim estimate --config`."""
    from vestim.pipeline import PipelineConfig

    try:
        cfg = PipelineConfig() if config is None else PipelineConfig.from_toml(config)
    except (VestimError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(cfg.to_toml(), nl=False)


@app.command("simulate")
def simulate_cmd(
    name: Annotated[str, typer.Argument(help="Maneuver name (see `vestim maneuvers`).")],
    out: Annotated[Path, typer.Option("--out", help="Output log (.csv or .parquet).")],
    mu: Annotated[float | None, typer.Option(help="Road friction (the maneuver's own "
                                             "surface parameter).")] = None,
    v0: Annotated[float | None, typer.Option(help="Initial speed, m/s.")] = None,
    drivetrain: Annotated[str | None, typer.Option(help="awd | fwd | rwd.")] = None,
    tire: Annotated[str | None, typer.Option(help="Tire plant: magic | lugre.")] = None,
    tc: Annotated[bool | None, typer.Option("--tc/--no-tc", help="Traction control.")] = None,
    abs_: Annotated[bool | None, typer.Option("--abs/--no-abs", help="ABS.")] = None,
    vehicle: SimVehicleOpt = "hashemi_suv",
    seed: Annotated[int, typer.Option(help="Sensor-noise seed.")] = 0,
    rate: Annotated[float, typer.Option(help="Sensor sampling rate, Hz.")] = 200.0,
    sensors: Annotated[str, typer.Option(help="default | realistic (vibration, 4× noise, "
                                         "quantised gyros and wheel speeds).")] = "default",
    roll_scale: Annotated[float, typer.Option(help="The plant rolls this many times as much "
                                              "as the vehicle file says.")] = 1.0,
) -> None:
    """Simulate a maneuver and write a spec log with every measured and ref_ channel."""
    from vestim.io import write_log
    from vestim.io.files import check_output_path
    from vestim.sim import get_maneuver

    try:
        check_output_path(out, suffixes=LOG_SUFFIXES)
        m = get_maneuver(name, mu=mu, v0=v0, drivetrain=drivetrain, tire=tire, tc=tc, abs_=abs_)
        t0 = time.perf_counter()
        _, log = _run(m, vehicle, seed, rate, f"simulating {name}", sensors, roll_scale)
        path = write_log(log, out, metadata=log.attrs)
    except (VestimError, ValueError, OSError, FloatingPointError) as exc:
        raise _fail(exc) from None
    console.print(rich.markup.escape(f"wrote {path} ({len(log)} samples, {log['t'].iloc[-1]:.1f} "
                                     f"s simulated in {time.perf_counter() - t0:.2f} s)"))


@app.command("estimate")
def estimate_cmd(
    log_path: Annotated[Path, typer.Argument(metavar="LOG", help="Drive log (.csv or .parquet).")],
    out: Annotated[Path, typer.Option("--out", help="Output log of estimates (.csv or .parquet).")],
    vehicle: VehicleOpt = "",
    velocity: Annotated[str | None, typer.Option(help="Velocity stage (default reference); `vestim "
                                                 "methods velocity` lists the choices.")] = None,
    fusion: Annotated[str | None, typer.Option(help="Corner-to-CG fusion (default axle); `vestim "
                                               "methods fusion` lists the choices.")] = None,
    force: Annotated[str | None, typer.Option(help="Longitudinal force (default ukf); `vestim "
                                              "methods force` lists the choices.")] = None,
    normal: Annotated[str | None, typer.Option(help="Load transfer (default static); `vestim "
                                               "methods normal` lists the choices.")] = None,
    gains: Annotated[Path | None, typer.Option(help="Gains file of `vestim design lpv` for "
                                               "--velocity lpv.")] = None,
    config: Annotated[Path | None, typer.Option(help="TOML file with a [pipeline] table (methods) "
                                                "and [pipeline.<table>] parameter tables "
                                                "(docs/configuration.md); the stage flags "
                                                "override its methods.")] = None,
    method: Annotated[str, typer.Option(help="pipeline (forces and velocities) | stiffness-pf "
                                        "(002 Algorithm 1) | stiffness-ekf (augmented-state "
                                        "EKF, 002 Sec. V; docs/results_stiffness.md).")] = "pipeline",
    particles: Annotated[int, typer.Option(help="Particles of stiffness-pf.")] = 500,
    seed: Annotated[int, typer.Option(help="Random seed of stiffness-pf.")] = 0,
    map_path: Annotated[Path | None, typer.Option(
        "--map", help="Channel map (TOML, docs/channel-map.md): LOG is then a raw recording "
        "read through it, as `vestim import`.")] = None,
) -> None:
    """Estimate tire forces and vehicle/corner velocities (or tire stiffness) from a measured log."""
    if map_path is not None and method != "pipeline":
        raise _fail(ValueError("--map works with --method pipeline; for other methods convert "
                               "the recording first with `vestim import`"))
    if method in STIFFNESS_METHODS:
        _estimate_stiffness(log_path, out, vehicle, particles, seed, method)
        return
    if method != "pipeline":
        raise _fail(ValueError(f"method {method!r}: use pipeline, "
                               + " or ".join(STIFFNESS_METHODS)))
    import dataclasses
    import itertools

    import pandas as pd

    from vestim.io import LogWriter, iter_log, load_vehicle, parquet_rows, read_log
    from vestim.io.files import check_output_path
    from vestim.io.sanity import GATE_ROWS, gate
    from vestim.pipeline import Pipeline, PipelineConfig
    from vestim.pipeline.provenance import estimate_metadata

    try:
        check_output_path(out, inputs=[log_path, map_path, config, gains], suffixes=LOG_SUFFIXES)
        veh = load_vehicle(vehicle)
        stages: dict[str, Any] = {k: v for k, v in (("force", force), ("normal", normal),
                                                    ("velocity", velocity), ("fusion", fusion))
                                  if v is not None}
        if gains is not None:
            stages["gains"] = str(gains)
        cfg = (dataclasses.replace(PipelineConfig.from_toml(config), **stages)
               if config is not None else PipelineConfig(**stages))
        radius = veh.body.wheel_radius
        pieces: Iterator[pd.DataFrame]
        if map_path is None and log_path.suffix.lower() in (".parquet", ".pq"):
            # A Parquet log streams through in pieces: bounded memory for any length.
            total = parquet_rows(log_path)
            pieces = iter_log(log_path, require=["measured"], wheel_radius=radius)
        else:
            log = (read_log(log_path, require=["measured"], wheel_radius=radius)
                   if map_path is None else _import_for_estimate(log_path, map_path, radius))
            total, pieces = len(log), iter([log])
        # The input gate (docs/input-checks.md) on the first GATE_ROWS rows: errors exit 2
        # before anything is written, warnings are kept.
        head: list[pd.DataFrame] = []
        while sum(map(len, head)) < GATE_ROWS and (piece := next(pieces, None)) is not None:
            head.append(piece)
        checked = gate(head[0] if len(head) == 1 else pd.concat(head, ignore_index=True),
                       veh, source=str(log_path))
        warnings = checked.warnings
        attrs = dict(head[0].attrs)  # the input's metadata: a channel-map import's import.*
        t0 = time.perf_counter()
        pipe = Pipeline(veh, cfg)
        with _Progress(f"estimating {log_path.name}") as progress, LogWriter(out, float32=True) as writer:
            for frame in pipe.run_pieces(itertools.chain(head, pieces), progress=progress,
                                         total=total):
                head = []  # the checked pieces are not held once estimated
                writer.write(frame)
            meta = estimate_metadata(pipe, vehicle, source=str(log_path), log_attrs=attrs,
                                     checked=checked, map_path=map_path)
            writer.metadata.update(meta)
        path, rows, channels = writer.path, writer.rows, len(writer.columns) - 1
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    esc = rich.markup.escape
    for a, b in pipe.gaps:
        console.print(esc(f"note: time gap {a:.3f} -> {b:.3f} s: the filters restarted after it"))
    for w in warnings:
        console.print(f"[yellow]warning:[/yellow] {esc(w.message)}")
    if meta.get("torque_source") != "measured":
        console.print(esc("note: the log has no wheel torques; F_x comes from the chassis equation "
                          "(m·a_x + drag) split by the vehicle file's [powertrain] "
                          "front_drive_share and brake_front_share (vestim.models.chassis)"))
    missing = [k.split("_")[0] for k in ("roll_source", "pitch_source")
               if meta.get(k) == "quasi_static"]
    if missing:
        console.print(f"note: no {'/'.join(missing)} rate: quasi-static attitude from the "
                      "accelerations (suspension dynamics in the load transfer are lost)")
    if meta.get("ax_source", "measured") != "measured":
        console.print(esc(f"note: no ax: a_x from the derivative of {meta['ax_source']} "
                          "(grade and slip detection degrade, docs/fewer-sensors.md)"))
    if meta.get("outputs_unavailable", "none") != "none":
        console.print(esc(f"note: no wheel speeds: velocities from {meta['speed_source']}; not "
                          "given (metadata outputs_unavailable): slip ratios, per-corner F_x, "
                          "mu_x, radius_scale, gnss_latency"))
    console.print(esc(f"wrote {path} ({rows} samples, {channels} channels, "
                      f"{time.perf_counter() - t0:.2f} s)"))


STIFFNESS_METHODS: dict[str, str] = {"stiffness-pf": "pf", "stiffness-ekf": "ekf"}
"""``vestim estimate --method`` names of the stiffness estimators → ``estimate_stiffness``'s method."""


def _estimate_stiffness(log_path: Path, out: Path, vehicle: str, particles: int,
                        seed: int, method: str = "stiffness-pf") -> None:
    from vestim.estimators.stiffness import estimate_stiffness
    from vestim.io import load_vehicle, read_log, write_log
    from vestim.io.files import check_output_path
    from vestim.io.sanity import gate

    try:
        check_output_path(out, inputs=[log_path], suffixes=LOG_SUFFIXES)
        veh = load_vehicle(vehicle)
        log = read_log(log_path)
        checked = gate(log, veh, source=str(log_path))  # the input gate of the pipeline path
        t0 = time.perf_counter()
        est = estimate_stiffness(log, veh, particles=particles, seed=seed,
                                 method=STIFFNESS_METHODS[method])
        path = write_log(est, out, metadata={"vehicle": veh.name, "method": method,
                                             "particles": str(particles), "seed": str(seed),
                                             "source": str(log_path), **checked.metadata()})
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for w in checked.warnings:
        console.print(f"[yellow]warning:[/yellow] {rich.markup.escape(w.message)}")
    console.print(rich.markup.escape(f"wrote {path} ({len(est)} samples, "
                                     f"{time.perf_counter() - t0:.2f} s)"))


def _import_for_estimate(src: Path, map_path: Path, wheel_radius: float):  # type: ignore[no-untyped-def]
    """A raw recording through a channel map, checked as `read_log` checks a log to estimate."""
    from vestim.io.channel_map import describe_report, import_log
    from vestim.io.log import validate_log

    log, report = import_log(src, map_path)
    for line in describe_report(report):
        console.print(rich.markup.escape(line))
    validate_log(log, require=["measured"], wheel_radius=wheel_radius,
                 source=f"{src} (through {map_path})")
    return log


@app.command("import")
def import_cmd(
    src: Annotated[Path, typer.Argument(metavar="SRC", help="Raw recording: CSV/Parquet, numpy "
                                        "folder, MDF4 (.mf4), ROS 2 bag (.db3/.mcap/folder).")],
    map_path: Annotated[Path, typer.Option("--map", help="Channel map (TOML, "
                                           "docs/channel-map.md).")],
    out: Annotated[Path, typer.Option("--out", help="Drive log to write (.csv or .parquet).")],
) -> None:
    """Convert a raw recording into a drive log through a channel map (units, frames, rates)."""
    from vestim.io import write_log
    from vestim.io.channel_map import describe_report, import_log
    from vestim.io.files import check_output_path

    try:
        check_output_path(out, inputs=[src, map_path], suffixes=LOG_SUFFIXES)
        log, report = import_log(src, map_path)
        path = write_log(log, out, metadata=report.metadata())
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for line in describe_report(report):
        console.print(rich.markup.escape(line))
    console.print(rich.markup.escape(f"wrote {path} ({len(log)} samples at {report.rate:g} Hz, "
                                     f"{len(log.columns) - 1} channels)"))


@app.command("channels")
def channels_cmd(
    src: Annotated[Path, typer.Argument(metavar="SRC", help="Recording: CSV/Parquet, numpy "
                                        "folder, MDF4 (.mf4), ROS 2 bag (.db3/.mcap/folder).")],
    dbc: Annotated[list[Path] | None, typer.Option("--dbc", help="DBC file decoding the MDF4's "
                                                   "raw CAN frames (repeat for several buses).")]
    = None,
    time: Annotated[str | None, typer.Option("--time", help="CSV/Parquet: the time column "
                                             "(default t, time or timestamp).")] = None,
    starter_map: Annotated[bool, typer.Option("--starter-map", help="Instead of the table, print "
                                              "a starter channel map (TOML) of the spec channels "
                                              "recognised by name and unit.")] = False,
) -> None:
    """List every signal of a recording with its unit, rate and time span (the addresses a
    channel map names), or print a starter channel map for it."""
    from rich.table import Table

    from vestim.io.listing import list_signals
    from vestim.io.listing import starter_map as make_map

    try:
        listing = list_signals(src, dbc=dbc or (), time=time)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    if starter_map:
        typer.echo(make_map(listing.signals, dbc=[p.resolve() for p in dbc or ()],
                            time=listing.time), nl=False)
        return
    esc = rich.markup.escape
    table = Table(title=esc(f"{src} ({listing.kind}): {len(listing.signals)} signals"))
    for col, justify in (("signal", "left"), ("unit", "left"), ("samples", "right"),
                         ("rate Hz", "right"), ("start s", "right"), ("end s", "right")):
        table.add_column(col, justify=justify)  # type: ignore[arg-type]
    for s in listing.signals:
        table.add_row(esc(s.address), esc(s.unit or "-"), str(s.samples), f"{s.rate_hz:.4g}",
                      f"{s.t_start:.6g}", f"{s.t_end:.6g}")
    Console(soft_wrap=True).print(table)
    for note in listing.notes:
        console.print(f"note: {esc(note)}")


@app.command("calibrate")
def calibrate_cmd(
    logs: Annotated[list[Path], typer.Argument(metavar="LOG...", help="Drive logs of one car "
                                               "(.csv or .parquet); ref_ channels are ignored.")],
    vehicle: Annotated[str, typer.Option("--vehicle", help="Base vehicle TOML file (or built-in "
                                         "name); kept for what the logs do not excite.")],
    out: Annotated[Path, typer.Option("--out", help="Calibrated vehicle file to write (.toml).")],
    report: Annotated[Path | None, typer.Option("--report", help="Folder for calibration.md "
                                                "and calibration.png.")] = None,
) -> None:
    """Identify wheel radii, IMU biases/scale/mounting, steering, body roll/pitch and tire
    stiffness from ordinary logs; write CAR.toml with a one-σ and the evidence of each value."""
    from vestim.design.calibrate import calibrate, write_calibrated, write_report
    from vestim.io.files import check_output_path

    try:
        base = Path(vehicle)
        check_output_path(out, inputs=[*logs, base if base.is_file() else None],
                          suffixes=(".toml",))
        with _Progress("calibrating") as progress:
            result = calibrate(logs, vehicle, progress=lambda _step, f: progress(f))
        path = write_calibrated(result, base if base.is_file() else None, out)
        md = write_report(result, report) if report is not None else None
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for log, checked in zip(logs, result.checks, strict=True):
        for w in checked.warnings:
            console.print(f"[yellow]warning:[/yellow] {rich.markup.escape(f'{log}: {w.message}')}")
    values = result.values
    idle = sorted(k for k, v in values.items() if not v.excited)
    kept = sorted(k for k, v in values.items() if v.excited and not v.used)
    console.print(rich.markup.escape(
        f"wrote {path}: {len(values) - len(idle)} values identified, {len(idle)} not excited"
        + (f" ({', '.join(idle)})" if idle else "")
        + (f"; nominal kept for {len(kept)} identified (not better on the held-out logs or "
           f"within 2σ: {', '.join(kept)})" if kept else "")
        + (f"; report {md}" if md is not None else "")))


@app.command("score")
def score_cmd(
    estimate: Annotated[Path, typer.Argument(metavar="ESTIMATE", help="Log of estimates.")],
    reference: Annotated[Path, typer.Argument(metavar="REFERENCE",
                                              help="Log with ref_ channels (e.g. a simulator log).")],
    json_out: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
    cover: Annotated[bool, typer.Option("--coverage", help="Also the σ coverage beside each "
                                        "score: the share of samples within 1σ and 2σ of the "
                                        "reference (68.3 / 95.4 % for an honest Gaussian σ).")]
    = False,
) -> None:
    """NRMS (000's definition), RMSE and max error per channel against the ref_ channels;
    with --coverage the share of samples within 1σ and 2σ beside them."""
    from vestim.io import read_log
    from vestim.metrics import coverage, score, to_json, to_markdown, with_coverage

    try:
        est, ref = read_log(estimate), read_log(reference)
        names = {"estimate_name": str(estimate), "reference_name": str(reference)}
        table = score(est, ref, **names)
        if cover:
            table = with_coverage(table, coverage(est, ref, **names))
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(to_json(table) if json_out else to_markdown(table))


@app.command("plot")
def plot_cmd(
    estimate: Annotated[Path, typer.Argument(metavar="ESTIMATE", help="Log of estimates.")],
    reference: Annotated[Path | None, typer.Argument(metavar="[REFERENCE]",
                                                     help="Log with ref_ channels.")] = None,
    out: Annotated[Path, typer.Option("--out", help="Output folder for the PNGs.")] = Path("out/plots"),
    vehicle: VehicleOpt = "",
) -> None:
    """Draw the papers' figure types (speeds with wheel speeds, CG and corner velocities, forces)."""
    from vestim.io import load_vehicle, read_log
    from vestim.report.figures import plot_estimate

    try:
        veh = load_vehicle(vehicle)
        files = plot_estimate(read_log(estimate), read_log(reference) if reference else None,
                              wheel_radius=veh.body.wheel_radius, out_dir=out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for f in files:
        typer.echo(str(f))


def _vehicle_of(attrs: Mapping[Any, Any], source: Path) -> str:
    """The vehicle an estimate names in its metadata: ``vehicle_file`` (a TOML path or a
    built-in name), else a built-in ``vehicle`` name; an error saying to pass ``--vehicle``
    when it names none that can be loaded."""
    from vestim.io.vehicle import BUILTIN_VEHICLES

    file, name = str(attrs.get("vehicle_file", "")), str(attrs.get("vehicle", ""))
    if file in BUILTIN_VEHICLES or (file and Path(file).is_file()):
        return file
    if not file and name in BUILTIN_VEHICLES:
        return name
    found = file and not file.startswith("none")
    said = (f"names the vehicle file {file!r}, which is not found" if found else
            f"names no vehicle file (vehicle {name!r})" if name else "names no vehicle")
    raise ValueError(f"{source}: its metadata {said}; pass --vehicle FILE (or a built-in name: "
                     f"{', '.join(BUILTIN_VEHICLES)})")


@app.command("report")
def report_cmd(
    estimate: Annotated[Path, typer.Argument(metavar="ESTIMATE", help="Log of estimates (a .parquet "
                                             "file also gives its metadata).")],
    reference: Annotated[Path | None, typer.Argument(
        metavar="[REFERENCE]", help="Log with ref_ channels (and omega_*, ax, ay): the log the "
        "estimate was made from.")] = None,
    out: Annotated[Path, typer.Option("--out", help="HTML file to write.")] = Path("report.html"),
    vehicle: Annotated[str | None, typer.Option(
        "--vehicle", help="Vehicle TOML file or built-in name for the wheel radius (default: "
        "the one the estimate's metadata names, vehicle_file).")] = None,
    title: Annotated[str | None, typer.Option(help="Page title.")] = None,
    unpaired: Annotated[bool, typer.Option(
        "--unpaired", help="Compare with a REFERENCE that is not the estimate's own log (its "
        "metadata 'source' or its time span differ); the report then says so.")] = False,
) -> None:
    """Write one self-contained interactive HTML report (plotly, works offline) of an estimate.

    REFERENCE must be the log the estimate was made from (its metadata 'source', the same time
    span); its measured channels go through the input gate of `vestim estimate`."""
    from vestim.io import load_vehicle, read_log
    from vestim.io.channels import MEASURED_REQUIRED
    from vestim.io.files import check_output_path
    from vestim.io.sanity import gate
    from vestim.report.data import check_pairing
    from vestim.report.html import write_html_report

    try:
        check_output_path(out, inputs=[estimate, reference], suffixes=(".html", ".htm"))
        est = read_log(estimate)
        veh = load_vehicle(vehicle if vehicle is not None else _vehicle_of(est.attrs, estimate))
        ref = read_log(reference) if reference else None
        meta = {"estimate": str(estimate), "reference": str(reference) if reference else "none",
                "vehicle": veh.name + ("" if vehicle is not None else " (from the estimate's "
                                       "metadata)"),
                "wheel_radius": f"{veh.body.wheel_radius:g} m"}
        if ref is not None:
            if unpaired:
                meta["pairing"] = "not checked (--unpaired): the reference may be another log"
            else:
                check_pairing(est, ref, str(reference))
            if set(MEASURED_REQUIRED) <= set(ref.columns):
                checked = gate(ref, veh, source=str(reference))
                meta["input_checks"] = (f"passed, {len(checked.warnings)} warning(s), not run: "
                                        + (", ".join(n.check for n in checked.not_run) or "none"))
                for w in checked.warnings:
                    console.print(f"[yellow]warning:[/yellow] {rich.markup.escape(w.message)}")
            else:
                meta["input_checks"] = "not run: the reference has no measured channels"
        path = write_html_report(est, ref, out, wheel_radius=veh.body.wheel_radius,
                                 metadata=meta, title=title or f"vestim report: {estimate.name}")
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(str(path))


@app.command("batch")
def batch_cmd(
    logs: Annotated[list[Path], typer.Argument(metavar="LOGS...", help="Log files and/or folders "
                                               "(every *.parquet, *.pq, *.csv inside; with --map "
                                               "also *.mf4, *.db3, *.mcap and bag folders).")],
    out: Annotated[Path, typer.Option("--out", help="Output folder: <stem>_estimate.parquet per "
                                      "log, summary.parquet, summary.md.")],
    vehicle: Annotated[str, typer.Option("--vehicle", help="Vehicle TOML or built-in name for "
                                         "every log, or auto: each log's own (<stem>.toml next "
                                         "to it, crossplant metadata/manifest.json, simulator "
                                         "metadata).")] = "auto",
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address (tcp://host:port),"
                                                  " or synchronous; default: a local cluster.")]
    = None,
    workers: Annotated[int, typer.Option(help="Worker processes of the local cluster.")] = 2,
    config: Annotated[Path | None, typer.Option(help="TOML file with a [pipeline] table.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Recompute logs whose output is up to "
                                        "date.")] = False,
    map_paths: Annotated[list[Path] | None, typer.Option(
        "--map", help="Channel map (TOML, docs/channel-map.md) importing the raw recordings "
        "(MDF4, ROS 2 bags); repeat with one map per source kind ([source] kind).")] = None,
    dashboard: Annotated[bool, typer.Option("--dashboard", help="Serve Dask's dashboard, print "
                                            "its link and open it in a browser.")] = False,
) -> None:
    """Estimate many logs in parallel on Dask; exit 1 if any log failed (see summary.md),
    130 if interrupted (run the same command again to resume)."""
    from rich.markup import escape

    from vestim.batch import BatchInterrupted, collect_logs, run_batch
    from vestim.pipeline import PipelineConfig

    def show_dashboard(link: str) -> None:
        import importlib.util
        import webbrowser

        console.print(f"Dask dashboard: {escape(link)}")
        if importlib.util.find_spec("bokeh") is None:
            console.print("note: Dask's dashboard needs bokeh, which is not installed (pip "
                          "install bokeh); the batch runs without it")
        elif console.is_terminal:
            webbrowser.open(link)

    try:
        cfg = PipelineConfig.from_toml(config) if config is not None else None
        paths = collect_logs(logs, exclude=out, raw=bool(map_paths))
        with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
                      "{task.total}"), TimeElapsedColumn(), console=console, transient=True,
                      disable=not console.is_terminal) as bar:
            task = bar.add_task(f"{len(paths)} logs", total=len(paths))
            summary = run_batch(paths, vehicle, out, config=cfg, scheduler=scheduler,
                                n_workers=workers, force=force, maps=map_paths or (),
                                dashboard=show_dashboard if dashboard else None,
                                progress=lambda done, _n: bar.update(task, completed=done))
    except (BatchInterrupted, KeyboardInterrupt) as exc:
        text = str(exc) if isinstance(exc, BatchInterrupted) else (
            "interrupted; run the same command again to resume: finished logs are skipped")
        console.print(f"[yellow]{escape(text)}[/yellow]")
        raise typer.Exit(code=130) from None
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for row in summary.table[summary.table["status"] == "failed"].itertuples(index=False):
        console.print(f"[red]failed:[/red] {escape(f'{row.log}: {row.error}')}")
    console.print(f"{len(summary.table)} logs: {summary.count('ok')} ok, {summary.count('skipped')}"
                  f" skipped, {summary.count('failed')} failed in {summary.wall_s:.1f} s; summary "
                  f"in {escape(str(summary.summary_md))}")
    if summary.failed:
        raise typer.Exit(code=1)


design_app = typer.Typer(no_args_is_help=True, rich_markup_mode=None,
                         help="Observer design: LMI certificates, LPV gains.")
analyze_app = typer.Typer(no_args_is_help=True, rich_markup_mode=None,
                          help="Offline analysis of observers over logs.")
app.add_typer(design_app, name="design")
app.add_typer(analyze_app, name="analyze")


@design_app.command("lpv")
def design_lpv_cmd(
    out: Annotated[Path, typer.Option("--out", help="Gains file to write (TOML).")],
    vehicle: VehicleOpt = "",
) -> None:
    """Synthesise wheel-speed-scheduled LPV observer gains (001 eq. (30)–(32), 004 eq. (26)–(35))."""
    from vestim.design import design_lpv
    from vestim.io import load_vehicle
    from vestim.io.files import check_output_path

    try:
        check_output_path(out, inputs=[vehicle if Path(vehicle).is_file() else None],
                          suffixes=(".toml",))
        schedule = design_lpv(load_vehicle(vehicle))
        path = schedule.save_gains(out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    console.print(rich.markup.escape(f"wrote {path}"))


@design_app.command("check")
def design_check_cmd(
    vehicle: VehicleOpt = "",
    gains: Annotated[Path | None, typer.Option(help="Gains file; default: the papers' constant "
                                               "gains.")] = None,
) -> None:
    """Certify the observer error dynamics (affine quadratic stability, H∞ γ); exit 1 if not verified."""
    from vestim.design import check_design
    from vestim.io import load_vehicle

    try:
        cert = check_design(load_vehicle(vehicle), gains)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(cert.summary())
    if not cert.verified:
        raise typer.Exit(code=1)


@analyze_app.command("observability")
def analyze_observability_cmd(
    log_path: Annotated[Path, typer.Argument(metavar="LOG", help="Drive log.")],
    out: Annotated[Path, typer.Option("--out", help="Output folder (figures and summary).")],
    vehicle: VehicleOpt = "",
) -> None:
    """Observability rank, Gramians and stochastic observability tests over a log (000 Sec. III)."""
    from vestim.design import analyze_observability
    from vestim.io import load_vehicle, read_log

    try:
        report = analyze_observability(read_log(log_path), load_vehicle(vehicle), out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(report.summary())


@app.command("demo")
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/demo"),
    vehicle: SimVehicleOpt = "hashemi_suv",
    seed: Annotated[int, typer.Option(help="Sensor-noise seed.")] = 0,
) -> None:
    """Simulate the default maneuver set, estimate, score and plot; print the NRMS table."""
    import numpy as np
    from rich.table import Table

    from vestim.io import load_vehicle, write_log
    from vestim.metrics import score
    from vestim.pipeline import Pipeline
    from vestim.report.figures import plot_estimate
    from vestim.report.plots import plot_simulation, save_figure
    from vestim.sim import DEFAULT_SET, get_maneuver

    table = Table(title=f"vestim demo on {rich.markup.escape(vehicle)}: NRMS [%] of the default pipeline "
                        "(worst corner for per-corner channels)")
    cols = ("vx", "vy", "vx_*", "fx_*", "fy_*", "fz_*")
    for col in ("maneuver", *cols, "R·ω̄ vx"):
        table.add_column(col, justify="right")
    try:
        veh = load_vehicle(vehicle)
        pipeline = Pipeline(veh)
        for name in DEFAULT_SET:
            m = get_maneuver(name)
            _, log = _run(m, vehicle, seed, 200.0, f"simulating {name}")
            write_log(log, out / f"{name}.parquet", metadata=log.attrs)
            save_figure(plot_simulation(log, veh.body.wheel_radius,
                                        title=f"{name}: {m.description}"), out / f"{name}.png")
            est = pipeline.run(log)
            write_log(est, out / f"{name}_estimate.parquet", metadata={"maneuver": name})
            plot_estimate(est, log, wheel_radius=veh.body.wheel_radius, out_dir=out / name)
            scores = score(est, log).set_index("channel")["nrms_pct"]
            cells = []
            for c in cols:
                cells.append(scores.filter(regex=f"^{c.replace('*', '(fl|fr|rl|rr)')}$").max())
            omega = log[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]].to_numpy()
            naive = veh.body.wheel_radius * omega.mean(axis=1)
            ref = log["ref_vx"].to_numpy()
            cells.append(100 * float(np.sqrt(np.mean((naive - ref) ** 2)) / np.abs(ref).max()))
            table.add_row(name, *(f"{v:.1f}" for v in cells))
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    Console().print(table)
    Console().print(rich.markup.escape(f"logs, estimates (.parquet) and figures (.png) written "
                                       f"to {out}/"))


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
