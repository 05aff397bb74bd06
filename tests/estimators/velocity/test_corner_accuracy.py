"""Accuracy of the corner velocity observers on the simulator (seed 0, force stage in the loop).

Metric: per-corner NRMS of v_xt (000 Sec. IV: RMS error / max |truth|), truth =
ref_vx_*, ref_vy_* rotated into the tire frame by δ; the worst corner is asserted.
Inputs are built from the measured channels only (the force stage's μ_x, μ_y and
the IMU), so the figures include the force stage's errors.

The observers' model is the average lumped LuGre tire *without* its road-friction
term (000 eq. (17), 001 eq. (20), 004 eq. (8)): it matches the LuGre plant only
while that term is small, σ0|v_r|/(θg) ≪ κR|ω|, i.e. for slip ratios below about
1 %. Maneuvers with small slip are asserted with a margin of ~2× over the measured
figure (seed-to-seed spread of the sensor noise). Where the model does not hold,
the failure is recorded with ``xfail(strict=True)`` and its measured size, so that
an improvement shows up as an XPASS to be documented (docs/results.md).
"""

import dataclasses

import numpy as np
import pytest

from tests.estimators.velocity.corner_data import SUV, nrms, reference_vxt, sim_case
from vestim.constants import CORNERS
from vestim.design.calibration import fit_lugre
from vestim.estimators.velocity.corner import CornerVelocityEstimator, KFParams, LPVParams
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import to_tire_frame

R = SUV.body.wheel_radius


def worst_nrms(name: str, tire: str, method: str, params: KFParams | LPVParams | None = None,
               tc: bool | None = None, vehicle: Vehicle = SUV) -> float:
    log, inp = sim_case(name, tire, tc)
    out = CornerVelocityEstimator(vehicle, method, params).run(inp)
    return float(nrms(out.vxt, reference_vxt(log, inp)).max())


ALL = [("lugre_kf", None), ("lugre_ukf", None), ("lpv", LPVParams.paper_001()),
       ("lpv", LPVParams.paper_004()), ("lpv", LPVParams.paper_004_scheduled())]
ALL_IDS = ["kf", "ukf", "lpv001", "lpv004", "lpv004s"]


@pytest.mark.parametrize(("method", "params"), ALL, ids=ALL_IDS)
@pytest.mark.parametrize(("name", "tire", "limit_kf", "limit_lpv"), [
    # measured (max over corners): KF/UKF 0.40 %, LPV 0.79–0.81 %; R·ω alone 1.22 %
    ("accel_brake", "lugre", 0.008, 0.016),
    # measured: KF/UKF 0.41 %, LPV 0.68–0.69 %; R·ω alone 1.06 %
    ("dlc_snow", "lugre", 0.008, 0.014),
    # Magic Formula plant, small slip: KF/UKF 0.16 %, LPV 0.63–0.64 %; R·ω 1.01 %
    ("dlc_snow", "magic", 0.004, 0.013),
])
def test_small_slip_accuracy(name: str, tire: str, limit_kf: float, limit_lpv: float, method: str,
                             params: KFParams | LPVParams | None) -> None:
    """Small-slip maneuvers (000 Fig. 6a accelerate/brake on μ 0.3, DLC on snow): every method
    beats the free-rolling guess R·ω and stays well inside 000's 6.6 % velocity NRMS."""
    limit = limit_lpv if method == "lpv" else limit_kf
    assert worst_nrms(name, tire, method, params) < limit


@pytest.mark.parametrize("tire", ["lugre", "magic"])
@pytest.mark.parametrize("method", ["lugre_kf", "lugre_ukf"])
def test_launch_on_ice_all_wheel_spin(method: str, tire: str) -> None:
    """Full-throttle launch on ice, TC off: all four wheels spin at slip ratio ≈ 0.99 for 9 s.

    The high-slip module flags the wheels at spin-up (|ω̇| criterion) and, with the
    default R̄_high = ∞, the filter integrates the kinematics while μ_x carries no
    information on v_rx. Measured: 0.49 % (LuGre plant), 1.23 % (Magic Formula plant,
    whose sliding μ_x = 0.054 stays above the 0.03 release level). Limits 2× that.
    """
    limit = {"lugre": 0.01, "magic": 0.025}[tire]
    assert worst_nrms("launch_ice", tire, method, tc=False) < limit


def test_ait_dry_moderate_slip_kf() -> None:
    """Acceleration-in-turn on dry (000 Sec. IV-A inputs): slip up to 0.54 on the front
    wheels at the second throttle step. KF measured 1.86 % (LuGre), 1.54 % (Magic Formula)
    against R·ω's 11.1 % and 35.3 %; limit 3 %."""
    assert worst_nrms("ait_dry", "lugre", "lugre_kf") < 0.03
    assert worst_nrms("ait_dry", "magic", "lugre_kf") < 0.03


@pytest.mark.xfail(strict=True, reason="LPV observers have no high-slip handling: in long "
                   "all-wheel spin they follow the friction-free tire model to v_xt ≈ R·ω "
                   "(measured NRMS 340 % LuGre, 907 % Magic Formula)")
@pytest.mark.parametrize("tire", ["lugre", "magic"])
def test_lpv_launch_on_ice_fails(tire: str) -> None:
    assert worst_nrms("launch_ice", tire, "lpv", tc=False) < 0.10


@pytest.mark.xfail(strict=True, reason="000's Q̄, R̄ read literally (Q̄ = q·I): the force update "
                   "still drags v̂_xt to R·ω in long slip (measured 274 % LuGre, 718 % Magic Formula)")
def test_kf_paper_values_launch_on_ice_fails() -> None:
    assert worst_nrms("launch_ice", "lugre", "lugre_kf", KFParams.paper(), tc=False) < 0.10


@pytest.mark.xfail(strict=True, reason="moderate sustained combined slip (step steer, driver "
                   "holding 60 km/h: slip ratio 5–9 %, slip angle ~10°) is below the high-slip "
                   "threshold but far outside the friction-free model's range (valid < ~1 %): "
                   "KF 5.26 %, LPV 4.90 %, R·ω alone 5.29 %")
def test_step_steer_sustained_slip_fails() -> None:
    assert worst_nrms("step_steer", "lugre", "lugre_kf") < 0.03


@pytest.mark.xfail(strict=True, reason="lateral LPV (001 eq. (38)) estimates |v_yt| at about "
                   "1/3 of the truth wherever the lateral tire is past its linear range (measured v_yt "
                   "NRMS 40.6 % LuGre, 26.5 % Magic Formula on the snow DLC)")
def test_lateral_lpv_dlc_snow_fails() -> None:
    log, inp = sim_case("dlc_snow", "lugre")
    out = CornerVelocityEstimator(SUV, "lpv").run(inp)
    vx = log[[f"ref_vx_{c}" for c in CORNERS]].to_numpy()
    vy = log[[f"ref_vy_{c}" for c in CORNERS]].to_numpy()
    truth = to_tire_frame(vx, vy, inp.delta)[1]
    assert nrms(out.vyt, truth).max() < 0.10


def test_fit_recovers_lugre_plant_parameters() -> None:
    """fit_lugre (calibration; reads ref_) on the LuGre plant's AiT dry log recovers the
    small-slip stiffness σ0x/κx = 75.97 to 2 % (measured 75.6) and the road's friction curve
    θμ_s, θμ_c with θ(μ = 1) ≈ 1.10 (measured 1.32, 0.89 for nominal 1.2, 0.8; 10 %)."""
    log, _ = sim_case("ait_dry", "lugre")
    tire = fit_lugre(log, SUV)
    nominal = SUV.tire
    assert tire.sigma0_x / tire.kappa_x == pytest.approx(nominal.sigma0_x / nominal.kappa_x, rel=0.02)
    assert tire.mu_s == pytest.approx(1.10 * nominal.mu_s, rel=0.1)
    assert tire.mu_c == pytest.approx(1.10 * nominal.mu_c, rel=0.1)
    assert tire.sigma1_x == nominal.sigma1_x  # not identifiable from steady state: kept


def test_fit_on_magic_formula_plant_and_rerun() -> None:
    """On the Magic Formula plant (small-slip stiffness kx = 20 per unit slip ratio) the fitted
    σ0x/κx drops from the nominal 76 to 26.5 (measured; limits 15–35), and the KF with the
    fitted tire is no worse on the same AiT (measured 1.54 % → 1.3 %)."""
    log, _ = sim_case("ait_dry", "magic")
    tire = fit_lugre(log, SUV)
    assert 15.0 < tire.sigma0_x / tire.kappa_x < 35.0
    fitted = dataclasses.replace(SUV, tire=tire)
    nominal_err = worst_nrms("ait_dry", "magic", "lugre_kf")
    fitted_err = worst_nrms("ait_dry", "magic", "lugre_kf", vehicle=fitted)
    assert fitted_err < nominal_err + 0.002
    assert np.isfinite(fitted_err)
