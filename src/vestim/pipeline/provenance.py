"""How an estimate was made, as string metadata: the one builder of ``vestim estimate``'s
Parquet metadata and of the ``DataFrame.attrs`` that :func:`vestim.estimate` returns.

Keys (every value a string; JSON where it is a list or an object):

- ``vehicle`` (its name), ``vehicle_file`` (the TOML path as given, the built-in's name, or
  ``"none (a Vehicle object)"``) and ``vehicle_sha256`` (SHA-256 of the file's bytes, of the
  built-in's; of the canonical JSON of a :class:`~vestim.io.vehicle.Vehicle` given as an
  object);
- ``force``, ``normal``, ``velocity``, ``fusion`` (the stages), ``config`` (the whole
  :class:`~vestim.pipeline.config.PipelineConfig`, JSON) and ``vestim_version``;
- ``source``: the log estimated (a path, or ``"DataFrame"``);
- the force stage's input sources (``torque_source``, ``ax_source``, ``roll_source``, …) and
  roll assumption (``roll_gradient_source``, …): docs/fewer-sensors.md;
- ``warnings``: the input gate's findings and the pipeline's v_y consistency warning;
  ``checks_not_run``: the gate's checks that could not run, with the reason;
  ``gaps``: the time gaps the filters restarted after, ``[[t_before, t_after], …]`` in s;
- for a log imported through a channel map (``vestim import`` or ``estimate --map``), its
  ``import.*`` keys (docs/channel-map.md): the recording (``import.source``), the map
  (``import.map``) and, when imported in the same run, the map's SHA-256
  (``import.map_sha256``), the source clock's time
  of the log's t = 0 (``import.t0_source_s``, s), the IMU mounting used
  (``import.mounting``), the rate and the import's gaps.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vestim.io.vehicle import BUILTIN_VEHICLES, Vehicle

if TYPE_CHECKING:
    from vestim.io.sanity import GateReport
    from vestim.pipeline import Pipeline

__all__ = ["IMPORT_PREFIX", "estimate_metadata", "vehicle_provenance"]

IMPORT_PREFIX = "import."
"""Prefix of the metadata a channel-map import writes (``ImportReport.metadata``), carried
from the input log into the estimate's."""


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def vehicle_provenance(vehicle: Vehicle | str | Path) -> dict[str, str]:
    """``vehicle``, ``vehicle_file`` and ``vehicle_sha256`` of a vehicle given as a TOML path,
    a built-in name or a :class:`~vestim.io.vehicle.Vehicle` (see the module docstring)."""
    if isinstance(vehicle, Vehicle):
        text = json.dumps(dataclasses.asdict(vehicle), default=str, sort_keys=True)
        return {"vehicle": vehicle.name, "vehicle_file": "none (a Vehicle object)",
                "vehicle_sha256": _sha256(text.encode())}
    p = Path(vehicle)
    if p.is_file():
        return {"vehicle": p.stem, "vehicle_file": str(p), "vehicle_sha256": _sha256(p.read_bytes())}
    name = str(vehicle)
    if name not in BUILTIN_VEHICLES:
        raise ValueError(f"vehicle {name!r} is neither a file nor one of "
                         f"{', '.join(BUILTIN_VEHICLES)}")
    data = (resources.files("vestim") / "data" / "vehicles" / f"{name}.toml").read_bytes()
    return {"vehicle": name, "vehicle_file": name, "vehicle_sha256": _sha256(data)}


def _import_metadata(attrs: Mapping[Any, Any], map_path: Path | None) -> dict[str, str]:
    """The input log's ``import.*`` metadata, with the SHA-256 of ``map_path``, the map the
    log was imported through in this run (a map named by an earlier import may have
    changed since, so it is not hashed)."""
    out = {str(k): str(v) for k, v in attrs.items() if str(k).startswith(IMPORT_PREFIX)}
    if map_path is not None:
        out[IMPORT_PREFIX + "map_sha256"] = _sha256(Path(map_path).read_bytes())
    return out


def estimate_metadata(pipe: Pipeline, vehicle: Vehicle | str | Path, *, source: str,
                      checked: GateReport | None = None,
                      log_attrs: Mapping[Any, Any] | None = None,
                      map_path: str | Path | None = None) -> dict[str, str]:
    """The metadata of an estimate that ``pipe`` has just made (after ``run`` or
    ``run_pieces``): the keys of the module docstring.

    Args:
        pipe: the pipeline that made the estimate (its configuration, input sources, gaps
            and v_y consistency figure are read).
        vehicle: the vehicle as the caller gave it (TOML path, built-in name or object).
        source: the estimated log's path, or a word for an in-memory log.
        checked: the input gate's report (:func:`vestim.io.sanity.gate`): its warnings and
            the checks it could not run.
        log_attrs: the input log's metadata (``df.attrs``); its ``import.*`` keys are kept.
        map_path: the channel map the log was imported through in this run (``estimate
            --map``), hashed into ``import.map_sha256``.
    """
    from vestim import __version__

    cfg = pipe.config
    unverified = pipe.unverified_warning()
    return {
        **vehicle_provenance(vehicle),
        "force": cfg.force, "normal": cfg.normal, "velocity": cfg.velocity, "fusion": cfg.fusion,
        "source": source, "vestim_version": __version__,
        "config": json.dumps(dataclasses.asdict(cfg), default=str, sort_keys=True),
        **pipe.force.input_sources, **pipe.force.roll_assumption,
        **(checked.metadata([unverified] if unverified else []) if checked is not None else
           {"warnings": json.dumps([unverified] if unverified else [], ensure_ascii=False)}),
        "gaps": json.dumps(pipe.gaps),
        **_import_metadata(log_attrs or {}, None if map_path is None else Path(map_path)),
    }
