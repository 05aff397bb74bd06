"""The package as a user meets it: version, top-level API, optional extras, compile cache."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import vestim
from vestim.errors import MissingDependencyError, VestimError, optional_import

ROOT = Path(__file__).resolve().parents[1]


def test_version_matches_the_installed_metadata():
    from importlib.metadata import version

    assert vestim.__version__ == version("vestim")
    from vestim.cli import app

    res = CliRunner().invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"vestim {vestim.__version__}"


def test_top_level_api_names_the_main_entry_points():
    for name in ("estimate", "Pipeline", "PipelineConfig", "load_vehicle", "read_log", "calibrate"):
        assert callable(getattr(vestim, name)), name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = vestim.nope  # type: ignore[attr-defined]


def test_import_vestim_loads_no_heavy_module():
    """`import vestim` must stay cheap: the estimators, numba and pandas load on first use."""
    code = ("import sys, vestim; heavy = [m for m in ('numba', 'pandas', 'scipy', 'matplotlib', "
            "'vestim.pipeline') if m in sys.modules]; print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_estimate_is_pipeline_run(tmp_path: Path):
    """vestim.estimate(path, vehicle) is read_log + Pipeline.run: identical arrays."""
    from vestim.io import load_vehicle, read_log, write_log
    from vestim.pipeline import Pipeline
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("step_steer"), veh, seed=0).iloc[:400]
    path = write_log(log, tmp_path / "log.parquet")
    a = vestim.estimate(path, "hashemi_suv")
    b = Pipeline(veh).run(read_log(path))
    assert list(a.columns) == list(b.columns)
    np.testing.assert_array_equal(a.to_numpy(), b.to_numpy())


def test_missing_extra_names_the_extra():
    with pytest.raises(MissingDependencyError, match=r"pip install 'vestim\[design\]'") as exc:
        optional_import("vestim_no_such_module", "design", "the LMI tools")
    assert isinstance(exc.value, VestimError) and isinstance(exc.value, ImportError)


def test_numba_cache_goes_to_the_user_cache_or_numba_cache_dir(tmp_path: Path):
    """A read-only install must not recompile in every process: the cache is not the package.
    And each version of the code has its own directory: Numba checks only a cached kernel's
    own file, so a changed callee would otherwise run stale (test below)."""
    code = "import vestim, numba; print(numba.config.CACHE_DIR)"
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env)
    from vestim._cache import code_fingerprint

    assert out.stdout.strip() == str(tmp_path / "xdg" / "vestim" / "numba" / code_fingerprint())
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env)
    assert out.stdout.strip() == str(tmp_path / "mine")


def test_the_cache_directory_changes_with_any_source_file(tmp_path: Path):
    """A copy of the package with one callee's file changed (pipeline/rows.py untouched) gets
    another cache directory, so its compiled composition cannot be the stale one."""
    import shutil

    import vestim
    from vestim import _cache

    pkg = Path(vestim.__file__).resolve().parent
    copy = tmp_path / "vestim"
    shutil.copytree(pkg, copy, ignore=shutil.ignore_patterns("__pycache__", "*.nb*"))
    code = ("import importlib.util, sys; spec = importlib.util.spec_from_file_location("
            f"'_c', {str(copy / '_cache.py')!r}); m = importlib.util.module_from_spec(spec); "
            "spec.loader.exec_module(m); print(m.code_fingerprint())")
    run = [sys.executable, "-c", code]
    same = subprocess.run(run, capture_output=True, text=True, check=True).stdout.strip()
    assert same == _cache.code_fingerprint()
    lon = copy / "estimators" / "force" / "longitudinal.py"
    lon.write_text(lon.read_text(encoding="utf-8") + "\n# changed\n", encoding="utf-8")
    changed = subprocess.run(run, capture_output=True, text=True, check=True).stdout.strip()
    assert changed != same


def test_license_file_is_shipped():
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License")
