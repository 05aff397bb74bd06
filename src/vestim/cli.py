"""Command-line interface: ``vestim maneuvers | simulate | demo``.

Errors a user can fix (bad option, unknown maneuver, invalid vehicle file)
print one clear line and exit with status 2, never a traceback.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from vestim.errors import VestimError
from vestim.io import load_vehicle, read_log, write_log
from vestim.metrics import score, to_json, to_markdown
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.report.figures import plot_estimate
from vestim.report.plots import plot_simulation, save_figure
from vestim.sim import DEFAULT_SET, SensorModel, get_maneuver, maneuver_names, simulate
from vestim.sim.maneuvers import Maneuver, describe

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Corner-based vehicle state and tire-force estimation.")
console = Console(stderr=True)

VehicleOpt = Annotated[str, typer.Option("--vehicle", help="Vehicle TOML file or built-in name "
                                         "(hashemi_suv, compact_car).")]


def _fail(exc: Exception) -> typer.Exit:
    console.print(f"[red]error:[/red] {exc}")
    return typer.Exit(code=2)


def _run(m: Maneuver, vehicle: str, seed: int, rate: float, label: str):  # type: ignore[no-untyped-def]
    """Simulate with a progress bar on the terminal (hidden when not interactive)."""
    veh = load_vehicle(vehicle)
    with Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                  console=console, transient=True, disable=not console.is_terminal) as bar:
        task = bar.add_task(label, total=1.0)
        log = simulate(m, veh, seed=seed, sensors=SensorModel(rate=rate),
                       progress=lambda f: bar.update(task, completed=f))
    return veh, log


@app.command("maneuvers")
def maneuvers_cmd() -> None:
    """List the maneuver library, one per line, name first."""
    for name in maneuver_names():
        typer.echo(f"{name}\t{describe(name)}")


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
    vehicle: VehicleOpt = "hashemi_suv",
    seed: Annotated[int, typer.Option(help="Sensor-noise seed.")] = 0,
    rate: Annotated[float, typer.Option(help="Sensor sampling rate, Hz.")] = 200.0,
) -> None:
    """Simulate a maneuver and write a spec log with every measured and ref_ channel."""
    try:
        m = get_maneuver(name, mu=mu, v0=v0, drivetrain=drivetrain, tire=tire, tc=tc, abs_=abs_)
        t0 = time.perf_counter()
        _, log = _run(m, vehicle, seed, rate, f"simulating {name}")
        path = write_log(log, out, metadata=log.attrs)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    console.print(f"wrote {path} ({len(log)} samples, {log['t'].iloc[-1]:.1f} s simulated in "
                  f"{time.perf_counter() - t0:.2f} s)")


@app.command("estimate")
def estimate_cmd(
    log_path: Annotated[Path, typer.Argument(metavar="LOG", help="Drive log (.csv or .parquet).")],
    out: Annotated[Path, typer.Option("--out", help="Output log of estimates (.csv or .parquet).")],
    vehicle: VehicleOpt = "hashemi_suv",
    velocity: Annotated[str, typer.Option(help="Velocity stage: fused (default) | reference | "
                                          "kinematic | kf | ukf | lpv.")] = PipelineConfig.velocity,
    fusion: Annotated[str, typer.Option(help="Corner-to-CG fusion: axle | adaptive | opinion "
                                        "(writes confidence_*).")] = PipelineConfig.fusion,
    force: Annotated[str, typer.Option(help="Longitudinal force: ukf | ukf_rw | pid | uio | "
                                       "naive.")] = PipelineConfig.force,
    normal: Annotated[str, typer.Option(help="Load transfer: static | dynamic.")] = PipelineConfig.normal,
    gains: Annotated[Path | None, typer.Option(help="Gains file of `vestim design lpv` for "
                                               "--velocity lpv.")] = None,
    config: Annotated[Path | None, typer.Option(help="TOML file with a [pipeline] table "
                                                "(overrides the stage flags).")] = None,
    method: Annotated[str, typer.Option(help="pipeline (forces and velocities) | stiffness-pf "
                                        "(002 Algorithm 1).")] = "pipeline",
    particles: Annotated[int, typer.Option(help="Particles of stiffness-pf.")] = 500,
    seed: Annotated[int, typer.Option(help="Random seed of stiffness-pf.")] = 0,
) -> None:
    """Estimate tire forces and vehicle/corner velocities (or tire stiffness) from a measured log."""
    if method == "stiffness-pf":
        _estimate_stiffness(log_path, out, vehicle, particles, seed)
        return
    if method != "pipeline":
        raise _fail(ValueError(f"method {method!r}: use pipeline or stiffness-pf"))
    try:
        veh = load_vehicle(vehicle)
        cfg = (PipelineConfig.from_toml(config) if config is not None
               else PipelineConfig(force=force, normal=normal, velocity=velocity, fusion=fusion,
                                   gains=str(gains) if gains else None))
        log = read_log(log_path, require=["measured"], wheel_radius=veh.body.wheel_radius)
        t0 = time.perf_counter()
        pipe = Pipeline(veh, cfg)
        est = pipe.run(log)
        meta = {"vehicle": veh.name, "force": cfg.force, "normal": cfg.normal,
                "velocity": cfg.velocity, "fusion": cfg.fusion, "source": str(log_path),
                **pipe.force.input_sources}
        path = write_log(est, out, metadata=meta)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    if meta.get("torque_source") != "measured":
        console.print("note: the log has no wheel torques; F_x comes from the chassis equation "
                      "(m·a_x + drag) split by the vehicle file's [powertrain] front_drive_share "
                      "and brake_front_share (vestim.models.chassis)")
    missing = [k.split("_")[0] for k in ("roll_source", "pitch_source")
               if meta.get(k) == "quasi_static"]
    if missing:
        console.print(f"note: no {'/'.join(missing)} rate: quasi-static attitude from the "
                      "accelerations (suspension dynamics in the load transfer are lost)")
    console.print(f"wrote {path} ({len(est)} samples, {len(est.columns) - 1} channels, "
                  f"{time.perf_counter() - t0:.2f} s)")


def _estimate_stiffness(log_path: Path, out: Path, vehicle: str, particles: int,
                        seed: int) -> None:
    from vestim.estimators.stiffness import estimate_stiffness

    try:
        veh = load_vehicle(vehicle)
        log = read_log(log_path)
        t0 = time.perf_counter()
        est = estimate_stiffness(log, veh, particles=particles, seed=seed)
        path = write_log(est, out, metadata={"vehicle": veh.name, "method": "stiffness-pf",
                                             "particles": str(particles), "seed": str(seed),
                                             "source": str(log_path)})
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    console.print(f"wrote {path} ({len(est)} samples, {time.perf_counter() - t0:.2f} s)")


@app.command("score")
def score_cmd(
    estimate: Annotated[Path, typer.Argument(metavar="ESTIMATE", help="Log of estimates.")],
    reference: Annotated[Path, typer.Argument(metavar="REFERENCE",
                                              help="Log with ref_ channels (e.g. a simulator log).")],
    json_out: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
) -> None:
    """NRMS (000's definition), RMSE and max error per channel against the ref_ channels."""
    try:
        table = score(read_log(estimate), read_log(reference), estimate_name=str(estimate),
                      reference_name=str(reference))
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(to_json(table) if json_out else to_markdown(table))


@app.command("plot")
def plot_cmd(
    estimate: Annotated[Path, typer.Argument(metavar="ESTIMATE", help="Log of estimates.")],
    reference: Annotated[Path | None, typer.Argument(metavar="[REFERENCE]",
                                                     help="Log with ref_ channels.")] = None,
    out: Annotated[Path, typer.Option("--out", help="Output folder for the PNGs.")] = Path("out/plots"),
    vehicle: VehicleOpt = "hashemi_suv",
) -> None:
    """Draw the papers' figure types (speeds with wheel speeds, CG and corner velocities, forces)."""
    try:
        veh = load_vehicle(vehicle)
        files = plot_estimate(read_log(estimate), read_log(reference) if reference else None,
                              wheel_radius=veh.body.wheel_radius, out_dir=out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    for f in files:
        typer.echo(str(f))


design_app = typer.Typer(no_args_is_help=True, help="Observer design: LMI certificates, LPV gains.")
analyze_app = typer.Typer(no_args_is_help=True, help="Offline analysis of observers over logs.")
app.add_typer(design_app, name="design")
app.add_typer(analyze_app, name="analyze")


@design_app.command("lpv")
def design_lpv_cmd(
    out: Annotated[Path, typer.Option("--out", help="Gains file to write (TOML).")],
    vehicle: VehicleOpt = "hashemi_suv",
) -> None:
    """Synthesise wheel-speed-scheduled LPV observer gains (001 eq. (30)–(32), 004 eq. (26)–(35))."""
    from vestim.design import design_lpv

    try:
        schedule = design_lpv(load_vehicle(vehicle))
        path = schedule.save_gains(out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    console.print(f"wrote {path}")


@design_app.command("check")
def design_check_cmd(
    vehicle: VehicleOpt = "hashemi_suv",
    gains: Annotated[Path | None, typer.Option(help="Gains file; default: the papers' constant "
                                               "gains.")] = None,
) -> None:
    """Certify the observer error dynamics (affine quadratic stability, H∞ γ); exit 1 if not verified."""
    from vestim.design import check_design

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
    vehicle: VehicleOpt = "hashemi_suv",
) -> None:
    """Observability rank, Gramians and stochastic observability tests over a log (000 Sec. III)."""
    from vestim.design import analyze_observability

    try:
        report = analyze_observability(read_log(log_path), load_vehicle(vehicle), out)
    except (VestimError, ValueError, OSError) as exc:
        raise _fail(exc) from None
    typer.echo(report.summary())


@app.command("demo")
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/demo"),
    vehicle: VehicleOpt = "hashemi_suv",
    seed: Annotated[int, typer.Option(help="Sensor-noise seed.")] = 0,
) -> None:
    """Simulate the default maneuver set, estimate, score and plot; print the NRMS table."""
    table = Table(title=f"vestim demo on {vehicle}: NRMS [%] of the default pipeline "
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
    Console().print(f"logs, estimates (.parquet) and figures (.png) written to {out}/")


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
