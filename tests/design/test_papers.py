"""The Lyapunov matrices printed in 001 eq. (29), (41) and 004 eq. (21), checked by eigenvalues.

Expected figures come from this package's own run (docs/results.md); they are
asserted with 1 % tolerance because the papers print 4-5 significant digits.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from vestim.design.lmi import ParameterBox
from vestim.design.papers import (
    PAPER_001_LATERAL,
    PAPER_001_LONGITUDINAL,
    PAPER_004,
    check_printed_lyapunov,
    gains_004_eq35,
)
from vestim.models.lpv import LuGreAxis


def test_001_eq29_holds_only_in_the_dual_form_and_only_with_corrected_matrices() -> None:
    # Dual form with the derived A0 (entry 1 − L1p1): λ_max = −361.7 (holds). With the printed
    # A0 (−L1p1) it fails (+88.6 at ω = 0, ω̇ = +800), so P was not computed from the printed
    # matrices — the printed entry is a typo. Multi-convexity fails either way (−170).
    dual = check_printed_lyapunov(PAPER_001_LONGITUDINAL, form="dual")
    literal = check_printed_lyapunov(PAPER_001_LONGITUDINAL, form="dual", literal=True)
    assert dual.verified and not literal.verified
    assert literal.checks[1].min_eig == pytest.approx(-88.61, rel=1e-2)
    assert dual.checks[2].min_eig == pytest.approx(-170.2, rel=1e-2)


def test_001_eq41_fails_at_high_wheel_speed() -> None:
    # Lateral P of 001 eq. (41): violates both forms on [0, 180] (dual: +2.19e5, worst near
    # ω = 168-180) but the dual form holds on [0, 100] (λ_max = −1345).
    full = check_printed_lyapunov(PAPER_001_LATERAL, form="dual")
    assert not full.verified
    assert -full.checks[1].min_eig == pytest.approx(2.189e5, rel=1e-2)
    low = check_printed_lyapunov(PAPER_001_LATERAL, form="dual", box=ParameterBox(0, 100, 800))
    assert low.verified and low.checks[1].min_eig == pytest.approx(1344.5, rel=1e-2)


def test_004_eq21_depends_on_the_unprinted_sigma1() -> None:
    # 004 never gives σ1x. With 001's 0.76 the printed P fails both forms; the dual form holds
    # for σ1x ≳ 0.92 (e.g. 1.0, λ_max = −5.42).
    assert not check_printed_lyapunov(PAPER_004, form="dual").verified
    assert not check_printed_lyapunov(PAPER_004, form="primal").verified
    case = replace(PAPER_004, axis=LuGreAxis(610.0, 1.0, 0.002, 8.0, 0.35))
    res = check_printed_lyapunov(case, form="dual")
    assert res.verified and res.checks[1].min_eig == pytest.approx(5.42, rel=1e-2)


def test_004_eq35_gains_and_their_pole() -> None:
    # At ω = 0: L1 = 2.83e4/2.38e4 = 1.189, L2 = 4822·7.34e4/9.51e5 = 372.2 (hand arithmetic).
    # Both denominators change sign between 150 and 155 rad/s: a pole beyond the 0-120 grid.
    l1, l2 = gains_004_eq35(np.array([0.0, 150.0, 155.0]))
    assert l1[0] == pytest.approx(1.189, rel=1e-3) and l2[0] == pytest.approx(372.2, rel=1e-3)
    assert l1[1] < 0 < l1[2] and l2[1] < 0 < l2[2]
