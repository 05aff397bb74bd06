"""Conformance of the corner velocity observers: shapes, batch == online, no ref_, NaNs, errors."""

import dataclasses
import itertools

import numpy as np
import pandas as pd
import pytest

from tests.estimators.velocity.corner_data import SUV, sim_case, synthetic, without_ref
from vestim.errors import LogFormatError
from vestim.estimators.force import ForceEstimator
from vestim.estimators.velocity.corner import (
    CornerVelocityEstimator,
    CornerVelocityInput,
    CornerVelocityOutput,
    HighSlipParams,
    KFParams,
    LPVParams,
)
from vestim.estimators.velocity.corner_inputs import corner_inputs

CASES = [("lugre_kf", None), ("lugre_ukf", None), ("lpv", None), ("lpv", LPVParams.paper_004()),
         ("lpv", LPVParams.paper_004_scheduled()), ("lugre_kf", KFParams.paper())]
IDS = ["kf", "ukf", "lpv001", "lpv004", "lpv004s", "kf_paper"]
FIELDS = [f.name for f in dataclasses.fields(CornerVelocityOutput)]


def assert_outputs_identical(a: CornerVelocityOutput, b: CornerVelocityOutput) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def concat(parts: list[CornerVelocityOutput]) -> CornerVelocityOutput:
    return CornerVelocityOutput(**{n: np.concatenate([getattr(p, n) for p in parts]) for n in FIELDS})


@pytest.mark.parametrize(("method", "params"), CASES, ids=IDS)
def test_batch_equals_sample_by_sample(method: str, params: KFParams | LPVParams | None) -> None:
    """advance over a whole simulator log == advance one sample at a time, bit for bit
    (same compiled kernel, same state), and == arbitrary chunks (launch on ice: the
    high-slip module switches during it)."""
    _, inp = sim_case("launch_ice", "lugre")
    inp = inp.slice(150, 750)  # standstill, launch and wheel spin
    batch = CornerVelocityEstimator(SUV, method, params).run(inp)
    est = CornerVelocityEstimator(SUV, method, params)
    online = concat([est.advance(inp.slice(k, k + 1)) for k in range(len(inp))])
    assert_outputs_identical(batch, online)
    est.reset()
    edges = [0, 7, 8, 100, 333, len(inp)]
    chunked = concat([est.advance(inp.slice(a, b)) for a, b in itertools.pairwise(edges)])
    assert_outputs_identical(batch, chunked)


def test_never_reads_reference_channels() -> None:
    """Dropping every ref_ column of the log (and of what the force stage sees) changes nothing."""
    log, _ = sim_case("dlc_snow", "lugre")
    full = corner_inputs(log, ForceEstimator(SUV).run(log), SUV)
    meas = without_ref(log)
    bare = corner_inputs(meas, ForceEstimator(SUV).run(meas), SUV)
    for method, params in CASES[:3]:
        a = CornerVelocityEstimator(SUV, method, params).run(full)
        b = CornerVelocityEstimator(SUV, method, params).run(bare)
        assert_outputs_identical(a, b)


@pytest.mark.parametrize(("method", "params"), CASES[:3], ids=IDS[:3])
def test_shapes_determinism_and_inputs_untouched(method: str,
                                                 params: KFParams | LPVParams | None) -> None:
    inp = synthetic(200, seed=7, planar=True)
    copies = {f.name: np.copy(getattr(inp, f.name)) for f in dataclasses.fields(inp)}
    a = CornerVelocityEstimator(SUV, method, params).run(inp)
    b = CornerVelocityEstimator(SUV, method, params).run(inp)
    assert_outputs_identical(a, b)
    for name, value in copies.items():
        np.testing.assert_array_equal(getattr(inp, name), value, err_msg=name)
    for name in FIELDS:
        assert getattr(a, name).shape == (200, 4), name
    assert a.high_slip.dtype == np.bool_
    assert np.all(np.isfinite(a.vxt))
    if method == "lpv":
        assert np.all(np.isnan(a.sigma_vxt)) and np.all(np.isfinite(a.vyt))
    else:
        assert np.all(a.sigma_vxt > 0) and np.all(np.isnan(a.vyt))
    cols = a.columns()
    assert "vxt_fl" in cols and "high_slip_rr" in cols
    assert ("sigma_vxt_fl" in cols) == (method != "lpv")
    assert ("vyt_fl" in cols) == (method == "lpv")


def test_caller_arrays_are_not_aliased() -> None:
    """The input keeps its own copies only when a conversion is needed; the kernels never write inputs."""
    inp = synthetic(50, seed=8)
    omega = inp.omega.copy()
    CornerVelocityEstimator(SUV, "lugre_kf").run(inp)
    np.testing.assert_array_equal(inp.omega, omega)


@pytest.mark.parametrize(("method", "params"), CASES[:3], ids=IDS[:3])
def test_missing_samples(method: str, params: KFParams | LPVParams | None) -> None:
    """NaN μ: prediction only (finite output); NaN ω or t: NaN output there, state untouched after."""
    inp = synthetic(300, seed=9, planar=True)
    mu_x = inp.mu_x.copy()
    mu_x[100:140, 1] = np.nan
    omega = inp.omega.copy()
    omega[200, 2] = np.nan
    t = inp.t.copy()
    t[250] = np.nan
    holey = dataclasses.replace(inp, mu_x=mu_x, omega=omega, t=t)
    out = CornerVelocityEstimator(SUV, method, params).run(holey)
    assert np.all(np.isfinite(out.vxt[100:140, 1]))
    assert np.isnan(out.vxt[200, 2]) and np.all(np.isfinite(out.vxt[201:250, 2]))
    assert np.all(np.isnan(out.vxt[250])) and np.all(np.isfinite(out.vxt[251:]))
    # A missing sample of one corner leaves the others exactly as without it.
    ref = CornerVelocityEstimator(SUV, method, params).run(dataclasses.replace(inp, mu_x=mu_x))
    np.testing.assert_array_equal(out.vxt[:250, [0, 1, 3]], ref.vxt[:250, [0, 1, 3]])


def test_errors_name_the_problem() -> None:
    inp = synthetic(20)
    with pytest.raises(ValueError, match="corner velocity method 'ekf'"):
        CornerVelocityEstimator(SUV, "ekf")
    with pytest.raises(ValueError, match="method 'lpv' takes LPVParams"):
        CornerVelocityEstimator(SUV, "lpv", KFParams())
    with pytest.raises(ValueError, match="takes KFParams"):
        CornerVelocityEstimator(SUV, "lugre_kf", LPVParams())
    with pytest.raises(ValueError, match=r"mu_x has shape \(20, 3\)"):
        dataclasses.replace(inp, mu_x=np.zeros((20, 3)))
    with pytest.raises(ValueError, match="yaw_rate has shape"):
        dataclasses.replace(inp, yaw_rate=np.zeros((20, 4)))
    with pytest.raises(ValueError, match="strictly increasing"):
        dataclasses.replace(inp, t=inp.t[::-1].copy())
    est = CornerVelocityEstimator(SUV, "lugre_kf")
    est.advance(inp)
    with pytest.raises(ValueError, match="call reset"):
        est.advance(inp)
    no_lat = CornerVelocityInput(t=inp.t, omega=inp.omega, mu_x=inp.mu_x, a_xt=inp.a_xt,
                                 delta=inp.delta, yaw_rate=inp.yaw_rate)
    with pytest.raises(ValueError, match="needs mu_y"):
        CornerVelocityEstimator(SUV, "lpv").run(no_lat)
    out = CornerVelocityEstimator(SUV, "lpv", LPVParams(lateral=None)).run(no_lat)
    assert np.all(np.isnan(out.vyt))
    with pytest.raises(ValueError, match=r"KFParams\.q"):
        KFParams(q=(1.0, -1.0, 1.0))
    with pytest.raises(ValueError, match="lambda_lower"):
        HighSlipParams(lambda_lower=0.3, lambda_upper=0.2)
    with pytest.raises(LogFormatError, match="yaw_rate"):
        log, _ = sim_case("dlc_snow", "lugre")
        corner_inputs(log.drop(columns=["yaw_rate"]), pd.DataFrame({"roll": [], "pitch": []}), SUV)
