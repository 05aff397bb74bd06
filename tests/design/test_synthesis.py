"""LPV gain synthesis (001 eq. (30)-(32), 004 eq. (26)-(35)), gains files and check_design.

Grids are small (9 points, verified on 201) to keep the suite fast; the full-size design
is timed in benchmarks/bench_design.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vestim.design import (
    DesignSpec,
    GainsFileError,
    check_design,
    design_lpv,
    load_gains,
    lugre_observer_plant,
)
from vestim.design.frequency import frequency_response
from vestim.design.lmi import LPVSystem
from vestim.io.vehicle import load_vehicle
from vestim.models import lpv

VEH = load_vehicle("hashemi_suv")
AX = lpv.longitudinal_axis(VEH)
SMALL = DesignSpec(n_grid=9)


@pytest.fixture(scope="module")
def schedule():  # type: ignore[no-untyped-def]
    return design_lpv(VEH, SMALL, directions=("longitudinal",))


def test_dc_gain_from_friction_term_to_velocity_error_is_one_at_standstill() -> None:
    # Why γ ≥ 1 for every observer (the floor that makes min γ degenerate): at ω = 0 the DC
    # transfer −A_e⁻¹B_e from Ω_z to e_vr is exactly −1 for any gains, by algebra
    # (e_vr row of A_e⁻¹B_e is [1, −L1/L2]). Checked for random gains to 1e-9.
    rng = np.random.default_rng(3)
    for _ in range(5):
        l1, l2 = rng.uniform(0.1, 2.0), rng.uniform(5, 500)
        a0, a1, be = lpv.affine_error_dynamics(l1, l2, AX)
        sys_ = LPVSystem.from_affine(a0, a1, be, None, np.eye(2))
        g = frequency_response(sys_, np.array([0.0]), np.array([0.0]))[0, 0]
        assert g[1, 0].real == pytest.approx(-1.0, abs=1e-9)
        assert g[1, 1].real == pytest.approx(l1 / l2, rel=1e-9)


def test_synthesised_certificate_is_verified_on_the_fine_grid(schedule) -> None:  # type: ignore[no-untyped-def]
    # The certificate (P, χ, γ) holds by eigenvalues on 201 points × rate vertices, both with
    # the rational gains P⁻¹χ and with the tabulated, linearly interpolated schedule.
    g = schedule.longitudinal
    c = g.certificate
    assert c is not None and c.verified and c.schedule_verified
    assert 1.0 <= c.gamma <= 1.1  # the floor is 1 (see the test above); slack 2 %
    assert c.gamma >= c.gamma_opt
    assert c.min_eig > 0


def test_designed_gains_keep_the_poles_in_the_disk_and_stable(schedule) -> None:  # type: ignore[no-untyped-def]
    # Frozen-ω eigenvalues of A − L C (001 eq. (25)) with the table's gains: Hurwitz and
    # |λ| ≤ 400 1/s (the default pole radius), on a grid finer than the table.
    g = schedule.longitudinal
    w = np.linspace(0, 180, 361)
    l1, l2 = g.gains(w)
    ae, _ = lpv.error_dynamics(w, l1, l2, AX)
    lam = np.linalg.eigvals(ae)
    assert lam.real.max() < 0
    assert np.abs(lam).max() <= 400.0 * (1 + 1e-6)


def test_gains_file_round_trip(schedule, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = schedule.save_gains(tmp_path / "g.toml")
    back = load_gains(path)
    a, b = schedule.longitudinal, back.longitudinal
    np.testing.assert_array_equal(a.omega, b.omega)
    np.testing.assert_array_equal(a.l1, b.l1)
    np.testing.assert_array_equal(a.l2, b.l2)
    assert a.axis == b.axis
    np.testing.assert_array_equal(a.certificate.lyapunov, b.certificate.lyapunov)
    assert b.certificate.gamma == a.certificate.gamma
    assert back.vehicle == "hashemi_suv" and back.lateral is None


def test_check_design_reverifies_a_stored_schedule(schedule, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = schedule.save_gains(tmp_path / "g.toml")
    cert = check_design(VEH, path, spec=SMALL)
    d = cert.directions["longitudinal"]
    assert d.stored is not None and d.stored.verified
    assert cert.verified and d.gamma is not None and d.gamma >= 1.0
    assert "stored certificate" in cert.summary()


def test_check_design_default_is_001_constant_gains() -> None:
    # With no gains file the constant gains of 001 Sec. IV are certified (both directions).
    cert = check_design("hashemi_suv")
    assert set(cert.directions) == {"longitudinal", "lateral"}
    assert cert.verified
    assert "L1 = 0.68, L2 = 183.1" in cert.summary()


def test_check_design_reports_destabilising_table_as_not_verified(tmp_path: Path) -> None:
    text = "\n".join([
        "format_version = 1", 'vehicle = "hashemi_suv"', 'gain_form = "innovation"',
        'scheduling = "abs_omega"', "[longitudinal]", "omega = [0.0, 180.0]",
        "L1 = [-1.0, -1.0]", "L2 = [-100.0, -100.0]", "sigma0 = 632.1", "sigma1 = 0.76",
        "sigma2 = 0.0016", "kappa = 8.32", "wheel_radius = 0.33", ""])
    path = tmp_path / "bad.toml"
    path.write_text(text)
    cert = check_design(VEH, path, spec=SMALL)
    d = cert.directions["longitudinal"]
    assert not cert.verified and not d.stable and d.gamma is None
    assert all(not r.feasible for r in d.stability)


@pytest.mark.parametrize(("edit", "match"), [
    (("format_version = 1", "format_version = 2"), "format_version"),
    (("kappa = 8.32", "kappa = 8.32\nfoo = 1"), "unknown key"),
    (("L2 = [-100.0, -100.0]", ""), "L2 is missing"),
    (("omega = [0.0, 180.0]", "omega = [180.0, 0.0]"), "increasing"),
])
def test_gains_file_errors_name_the_key(tmp_path: Path, edit: tuple[str, str], match: str) -> None:
    text = "\n".join([
        "format_version = 1", 'vehicle = "v"', 'gain_form = "innovation"',
        'scheduling = "abs_omega"', "[longitudinal]", "omega = [0.0, 180.0]",
        "L1 = [-1.0, -1.0]", "L2 = [-100.0, -100.0]", "sigma0 = 632.1", "sigma1 = 0.76",
        "sigma2 = 0.0016", "kappa = 8.32", "wheel_radius = 0.33", ""]).replace(*edit)
    path = tmp_path / "g.toml"
    path.write_text(text)
    with pytest.raises(GainsFileError, match=match):
        load_gains(path)


def test_plant_is_the_corner_model() -> None:
    # The synthesis plant evaluates to 001 eq. (22)-(23) at every ω (exact).
    plant = lugre_observer_plant(AX)
    w = np.array([0.0, 60.0, 180.0])
    a, cy = plant.matrices(w)
    np.testing.assert_allclose(a, lpv.state_matrix(w, AX), rtol=1e-15)
    np.testing.assert_allclose(cy, lpv.output_matrix(w, AX), rtol=1e-15)
    np.testing.assert_allclose(plant.f, lpv.measurement_disturbance_matrix(AX))
