"""Published observer data of 001 and 004, and checks of the Lyapunov matrices they print.

Cases (tire data, constant gains, operating region, printed P(ω)):

- 001 longitudinal, Sec. IV-A1: σ0x = 632.1, σ1x = 0.76, σ2x = 0.0016, κx = 8.32,
  R = 0.33, L1x = 0.68, L2x = 183.1 (innovation form), |ω| ≤ 180, |ω̇| ≤ 800; eq. (29).
- 001 lateral, Sec. IV-B (Remark 2): σ0y = 181.5, σ1y = 0.81, σ2y = 0.001, κy = 12.84,
  R = 0.33, L1y = 1.11, L2y = 16.7, |ω̇| ≤ 800 (|ω| ≤ 180 as in the longitudinal case); eq. (41).
- 004 Sec. III-C: σ0x = 610, σ2x = 0.002, κ = 8, R = 0.35 (Fig. 3 data), L1 = 0.65,
  L2 = 197 (output-derivative form, eq. (10)), |ω| ≤ 180, |ω̇| ≤ 600; eq. (21).
  004 never gives σ1x; :data:`SIGMA1_004` assumes 001's 0.76 (same vehicle and group).

The "literal" variants use the printed affine matrices (001 eq. (26) with
A0(1,2) = −L1 p1; 004 eq. (20) with a1(1,1) = −κR); the default uses the matrices
derived from the LuGre equations (:mod:`vestim.models.lpv`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vestim.design.analysis import check_lyapunov
from vestim.design.lmi import FArray, Form, LMIResult, LPVSystem, ParameterBox
from vestim.models.lpv import GainForm, LuGreAxis, affine_error_dynamics

__all__ = [
    "PAPER_001_LATERAL",
    "PAPER_001_LONGITUDINAL",
    "PAPER_004",
    "PAPER_CASES",
    "REFERENCE_GAINS",
    "SIGMA1_004",
    "PaperCase",
    "check_printed_lyapunov",
    "gains_004_eq35",
]

SIGMA1_004 = 0.76
"""σ1x for 004 (not printed there); 001's value for the same SUV."""

REFERENCE_GAINS: dict[str, tuple[float, float]] = {
    "longitudinal": (0.68, 183.1),
    "lateral": (1.11, 16.7),
}
"""Constant innovation-form gains (L1, L2) of 001 Sec. IV (found by road tests there)."""


@dataclass(frozen=True)
class PaperCase:
    """One published stability analysis: data, gains and the printed P(ω) = P0 + ωP1."""

    name: str
    equation: str
    axis: LuGreAxis
    gains: tuple[float, float]
    form: GainForm
    box: ParameterBox
    printed_p: FArray

    def system(self, literal: bool = False) -> LPVSystem:
        """Error dynamics ė = (a0 + |ω| a1) e + B_e Ω, output e_vr (derived or literal matrices)."""
        a0, a1, be = affine_error_dynamics(*self.gains, self.axis, self.form)
        a0, a1 = a0.copy(), a1.copy()
        if literal and self.form == "innovation":
            a0[0, 1] -= 1.0  # 001 eq. (26) prints −L1 p1
        if literal and self.form == "output_derivative":
            a1[0, 0] = -self.axis.decay_per_omega  # 004 eq. (20) prints −κR
        return LPVSystem.from_affine(a0, a1, be, None, np.array([[0.0, 1.0]]), name=self.name)


PAPER_001_LONGITUDINAL = PaperCase(
    name="001 longitudinal", equation="001 eq. (29)",
    axis=LuGreAxis(632.1, 0.76, 0.0016, 8.32, 0.33), gains=(0.68, 183.1), form="innovation",
    box=ParameterBox(0.0, 180.0, 800.0),
    printed_p=np.array([[[1.2176, 115.35], [115.35, 80379.0]],
                        [[-0.0011, -0.2227], [-0.2227, -67.969]]]))

PAPER_001_LATERAL = PaperCase(
    name="001 lateral", equation="001 eq. (41)",
    axis=LuGreAxis(181.5, 0.81, 0.001, 12.84, 0.33), gains=(1.11, 16.7), form="innovation",
    box=ParameterBox(0.0, 180.0, 800.0),
    printed_p=np.array([[[4.7718, 154.87], [154.87, 75627.0]],
                        [[-0.0070, 0.0038], [0.0038, -0.0013]]]))

PAPER_004 = PaperCase(
    name="004 longitudinal", equation="004 eq. (21)",
    axis=LuGreAxis(610.0, SIGMA1_004, 0.002, 8.0, 0.35), gains=(0.65, 197.0),
    form="output_derivative", box=ParameterBox(0.0, 180.0, 600.0),
    printed_p=np.array([[[0.024, -3.54], [-3.54, 2744.0]],
                        [[1e-4, 0.005], [0.005, -11.43]]]))

PAPER_CASES: tuple[PaperCase, ...] = (PAPER_001_LONGITUDINAL, PAPER_001_LATERAL, PAPER_004)


def check_printed_lyapunov(case: PaperCase, *, form: Form = "primal", literal: bool = False,
                           box: ParameterBox | None = None, n_verify: int = 1801) -> LMIResult:
    """Do the printed P(ω) satisfy the paper's conditions? Eigenvalues on a fine ω grid.

    ``form="primal"`` is the condition as printed (001 eq. (28), 004 eq. (18));
    ``form="dual"`` reads P(ω) as the Q(ω) of ``A Q + Q Aᵀ − ω̇ Q′ ≺ 0``
    (Lyapunov function eᵀQ⁻¹e, as MATLAB's ``pdlstab`` returns it).
    """
    b = box or case.box
    name = f"{case.equation} ({case.name}, {form}{', printed matrices' if literal else ''})"
    return check_lyapunov(case.system(literal), b, case.printed_p, form=form, n_verify=n_verify,
                          problem=name)


def gains_004_eq35(omega: FArray | float) -> tuple[FArray, FArray]:
    """004 eq. (35): LPV gains (output-derivative form) designed on ω ∈ [0, 120] rad/s.

    L1 = (1.78ω² − 50.1ω − 2.83e4)/(0.0221ω² + 154ω − 2.38e4),
    L2 = 4822(2.76ω² + 150ω − 7.34e4)/(0.885ω² + 6140ω − 9.51e5).
    Both denominators vanish near ω ≈ 151–154 rad/s, beyond the design grid.
    """
    w = np.asarray(omega, float)
    l1 = (1.78 * w**2 - 50.1 * w - 2.83e4) / (0.0221 * w**2 + 154.0 * w - 2.38e4)
    l2 = 4822.0 * (2.76 * w**2 + 150.0 * w - 7.34e4) / (0.885 * w**2 + 6140.0 * w - 9.51e5)
    return l1, l2
