"""The method registry and the pipeline configuration: every method listed once, defaults from
the registry, every parameter settable from TOML, and clear errors."""

import math
from dataclasses import fields, replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from vestim.cli import app
from vestim.estimators import registry
from vestim.estimators.force.longitudinal import METHODS as FORCE_METHODS
from vestim.estimators.force.normal import MODES
from vestim.estimators.fusion import FUSION_METHODS
from vestim.estimators.velocity.corner import METHODS as CORNER_OBSERVERS
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig, PipelineConfigError
from vestim.pipeline.config import PARAMETER_TABLES

SUV = load_vehicle("hashemi_suv")


def test_registry_lists_what_the_estimators_accept():
    """The registry's names are exactly the methods each estimator family's own check accepts
    (the force stage's ``METHODS``, the load modes, the fusion methods), with one default each:
    a method registered but not implemented, or implemented but not registered, fails here."""
    assert set(registry.names("force")) == set(FORCE_METHODS)
    assert set(registry.names("normal")) == set(MODES)
    assert set(registry.names("fusion")) == set(FUSION_METHODS)
    # the default first, then in registration order
    assert registry.names("velocity") == ("reference", "fused", "kinematic", "kf", "ukf", "lpv")
    for m in registry.methods("velocity"):  # the corner observer each runs exists
        assert m.corner is None or m.corner in CORNER_OBSERVERS, (m.name, m.corner)
    for stage in registry.STAGES:
        assert sum(m.default for m in registry.methods(stage)) == 1, stage
        for m in registry.methods(stage):
            assert set(m.tables) <= set(PARAMETER_TABLES), (stage, m.name, m.tables)


def test_config_defaults_are_the_registry_defaults():
    cfg = PipelineConfig()
    assert (cfg.force, cfg.normal, cfg.velocity, cfg.fusion) == tuple(
        registry.default(s) for s in ("force", "normal", "velocity", "fusion"))


def test_registering_twice_or_a_second_default_is_refused():
    with pytest.raises(ValueError, match="registered twice"):
        registry.register("fusion", "axle", "again")
    with pytest.raises(ValueError, match="two default methods"):
        registry.register("fusion", "median", "a second default", default=True)
    with pytest.raises(registry.UnknownMethodError, match="stage 'steering'"):
        registry.register("steering", "x", "no such stage")
    assert "median" not in registry.names("fusion")


def test_registry_holds_each_methods_callable_and_params():
    """``register`` keeps what it decorates: the fusion functions, the force and corner kernels,
    the stiffness estimator classes, each with its Params class and its code (the order of
    registration: ``ukf`` 0 … ``naive`` 4, as the compiled pipeline dispatches on them); the
    corner observers and stiffness estimators are kinds of their own (``PARTS``), not
    pipeline stages."""
    from vestim.estimators import fusion
    from vestim.estimators.force import longitudinal
    from vestim.estimators.stiffness import AugmentedEKF, NoiseAdaptivePF, StiffnessConfig
    from vestim.estimators.velocity.lpv_observer import LPVParams, lpv_kernel
    from vestim.estimators.velocity.lugre_kf import KFParams, lugre_kf_kernel

    force = {m.name: m for m in registry.methods("force")}
    assert [(n, force[n].code) for n in FORCE_METHODS] == [
        ("ukf", 0), ("ukf_rw", 1), ("pid", 2), ("uio", 3), ("naive", 4)]
    assert force["ukf"].impl is longitudinal.ukf_kernel
    assert force["ukf"].params is longitudinal.UKFParams
    assert force["naive"].impl is longitudinal.naive_kernel and force["naive"].params is None
    assert [m.impl for m in registry.methods("fusion")] == [
        fusion._fixed, fusion._adaptive, fusion._opinion]
    corner = {m.name: m for m in registry.methods("corner")}
    assert tuple(corner) == CORNER_OBSERVERS == ("lugre_kf", "lugre_ukf", "lpv")
    assert (corner["lugre_ukf"].impl, corner["lugre_ukf"].params) == (lugre_kf_kernel, KFParams)
    assert (corner["lpv"].impl, corner["lpv"].params) == (lpv_kernel, LPVParams)
    stiffness = registry.methods("stiffness")
    assert [m.name for m in stiffness] == ["pf", "augpf", "rls", "ekf"]
    assert (stiffness[0].impl, stiffness[-1].impl) == (NoiseAdaptivePF, AugmentedEKF)
    assert {m.params for m in stiffness} == {StiffnessConfig}
    assert registry.PARTS == ("corner", "stiffness")
    assert not set(registry.PARTS) & set(registry.STAGES)
    decorate = registry.register("fusion", "median_test", "a test method")
    try:
        assert decorate(len) is len and registry.lookup("fusion", "median_test").impl is len
        with pytest.raises(ValueError, match="already has its callable"):
            decorate(abs)  # a second callable for the same method
    finally:
        del registry._REGISTRY["fusion"]["median_test"]


def test_cli_methods_lists_every_registered_method():
    res = CliRunner().invoke(app, ["methods"])
    assert res.exit_code == 0, res.output
    rows = [line.split("\t") for line in res.output.splitlines()]
    assert [(r[0], r[1].rstrip("*")) for r in rows] == [
        (s, m.name) for s in registry.STAGES for m in registry.methods(s)]
    assert {r[1] for r in rows if r[0] == "velocity" and r[1].endswith("*")} == {"reference*"}
    bad = CliRunner().invoke(app, ["methods", "steering"])
    assert bad.exit_code == 2 and "stage 'steering'" in bad.output


def test_default_toml_round_trips(tmp_path):
    """`vestim config` writes every parameter; reading it back gives the default config."""
    res = CliRunner().invoke(app, ["config"])
    assert res.exit_code == 0, res.output
    f = tmp_path / "full.toml"
    f.write_text(res.output)
    assert PipelineConfig.from_toml(f) == PipelineConfig()
    for name in PARAMETER_TABLES:
        assert f"[pipeline.{name}]" in res.output


def _float_fields() -> list[tuple[str, str]]:
    return [(table, f.name) for table, cls in PARAMETER_TABLES.items() for f in fields(cls)
            if isinstance(getattr(getattr(PipelineConfig(), table), f.name), float)
            and math.isfinite(getattr(getattr(PipelineConfig(), table), f.name))]


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(_float_fields()), st.floats(1.05, 3.0))
def test_any_float_parameter_is_read_from_its_table(tmp_path_factory, where, scale):
    """Scaling any float parameter in its [pipeline.<table>] (by 1.05–3) reaches the config,
    and nothing else changes; a scale the table's own range check refuses is reported with the
    table's name."""
    table, key = where
    default = getattr(PipelineConfig(), table)
    value = getattr(default, key) * scale
    f = tmp_path_factory.mktemp("cfg") / "p.toml"
    f.write_text(f"[pipeline.{table}]\n{key} = {value!r}\n")
    try:
        cfg = PipelineConfig.from_toml(f)
    except PipelineConfigError as exc:
        assert f"[pipeline.{table}]" in str(exc)
        return
    assert cfg == replace(PipelineConfig(), **{table: replace(default, **{key: value})})


def test_nested_tables_and_tuples(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[pipeline]\nvelocity = "kf"\n[pipeline.force_params.ukf]\nq_acc = 200\n'
                 '[pipeline.corner]\nq = [1e-9, 1e-7, 2e-4]\n[pipeline.corner.high_slip]\n'
                 'accel_window = 50\n')
    cfg = PipelineConfig.from_toml(f)
    assert cfg.force_params.ukf.q_acc == 200.0 and isinstance(cfg.force_params.ukf.q_acc, float)
    assert cfg.corner.q == (1e-9, 1e-7, 2e-4) and cfg.corner.high_slip.accel_window == 50
    pipe = Pipeline(SUV, cfg)
    assert pipe.force.config.ukf.q_acc == 200.0 and pipe.force.config.longitudinal == "ukf"
    assert pipe.corner is not None and pipe.corner.params == cfg.corner


@pytest.mark.parametrize(("text", "message"), [
    ('[pipeline.reference]\ngate = "x"\n', "pipeline.reference.gate = 'x': expected a number"),
    ("[pipeline.reference]\ngate = true\n", "expected a number"),
    ("[pipeline.refrence]\ngate = 1\n", "unknown key 'refrence'; allowed: force, normal"),
    ("[pipeline.reference]\ngait = 1\n", "[pipeline.reference] has unknown key 'gait'"),
    ('[pipeline]\nvelocity = "kff"\n', "velocity method 'kff': use one of reference, fused"),
    ('[pipeline.force_params]\nnormal = "static"\n', "normal = … in [pipeline]"),
    ("[pipeline.corner]\nq = [1, 2]\n", "pipeline.corner.q = [1, 2]: expected 3 values"),
    ("[pipeline.corner.high_slip]\naccel_window = 1.5\n", "expected an integer"),
    ("[pipeline.health]\nhold_s = -1\n", "[pipeline.health]: health hold_s = -1.0 must be"),
    ("[pipeline.reference\n", "not valid TOML"),
    ("[other]\n", "no [pipeline] table"),
])
def test_errors_name_the_file_table_and_key(tmp_path, text, message):
    f = tmp_path / "p.toml"
    f.write_text(text)
    with pytest.raises(PipelineConfigError) as info:
        PipelineConfig.from_toml(f)
    assert message in str(info.value) and str(f) in str(info.value)


def test_cli_config_completes_a_file_with_the_defaults(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[pipeline]\nvelocity = "kinematic"\n')
    res = CliRunner().invoke(app, ["config", str(f)])
    assert res.exit_code == 0 and 'velocity = "kinematic"' in res.output


def test_docs_configuration_names_every_table_and_method():
    """docs/configuration.md is the user's reference: every parameter table and every
    registered method must be in it."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "configuration.md").read_text(
        encoding="utf-8")
    for table, cls in PARAMETER_TABLES.items():
        assert f"`[pipeline.{table}]`" in text and cls.__name__ in text, table
    for stage in registry.STAGES:
        for m in registry.methods(stage):
            assert f"`{m.name}`" in text, (stage, m.name)
