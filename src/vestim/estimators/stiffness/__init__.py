"""Tire-stiffness and vehicle-state estimation after 002 (Berntorp & Di Cairano).

Public API:

* :func:`estimate_stiffness` — log in, estimate log out (Algorithm 1 or a baseline).
* :class:`NoiseAdaptivePF` (Algorithm 1), :class:`AugmentedPF`, :class:`RlsKalman`,
  :class:`AugmentedEKF` — the estimators on prepared inputs.
* :class:`StiffnessPrior`, :class:`StiffnessConfig` — nominal stiffness and tuning.
* :func:`prepare_inputs` — log → model inputs and measurements.

Modules: ``model`` (single-track model, 002 eq. (1)–(12)), ``pf`` (Algorithm 1
kernel), ``draws`` (the kernel's random stream), ``augpf``, ``baselines`` (RLS + KF,
EKF), ``inputs``, ``config``, ``estimator``.
"""

from vestim.estimators.stiffness.config import StiffnessConfig, StiffnessPrior
from vestim.estimators.stiffness.estimator import (
    METHODS,
    AugmentedEKF,
    AugmentedPF,
    NoiseAdaptivePF,
    RlsKalman,
    StiffnessResult,
    estimate_stiffness,
)
from vestim.estimators.stiffness.inputs import StiffnessInputs, prepare_inputs

__all__ = ["METHODS", "AugmentedEKF", "AugmentedPF", "NoiseAdaptivePF", "RlsKalman",
           "StiffnessConfig", "StiffnessInputs", "StiffnessPrior", "StiffnessResult",
           "estimate_stiffness", "prepare_inputs"]
