"""Observer design and analysis toolkit (issue 5): LMI certificates, LPV gain synthesis,
observability and frequency-response analysis of the LuGre corner observers.

Public entry points (the CLI wires these):

- :func:`design_lpv` → :class:`GainSchedule` (``save_gains``/``load_gains``);
- :func:`check_design` → :class:`Certificate` (``summary()``);
- :func:`analyze_observability` → :class:`ObservabilityReport`.

Lower-level tools: :func:`affine_quadratic_stability`, :func:`hinf_performance`,
:func:`check_lyapunov`, :func:`synthesize_observer`, :func:`frequency_response`,
the observability functions of :mod:`vestim.design.observability`.
LMIs are solved with cvxpy + Clarabel (SCS as fallback) and every certificate
is verified by eigenvalues on a fine grid in original units.
"""

from vestim.design.analysis import affine_quadratic_stability, check_lyapunov, hinf_performance
from vestim.design.frequency import frequency_response, frozen_hinf_norm, plot_frequency_response
from vestim.design.lmi import LMICheck, LMIResult, LPVSystem, ParameterBox
from vestim.design.observability import (
    ObservabilityReport,
    StochasticObservability,
    analyze_observability,
    controllability_gramian,
    ltv_observability_matrix,
    observability_gramian,
    stochastic_observability,
)
from vestim.design.observer import (
    Certificate,
    DesignSpec,
    DirectionCertificate,
    check_design,
    design_lpv,
    lugre_observer_plant,
)
from vestim.design.synthesis import ObserverPlant, SynthesisResult, synthesize_observer
from vestim.estimators.velocity.lpv_gains import (
    GainSchedule,
    GainsFileError,
    ObserverGains,
    StoredCertificate,
    load_gains,
    save_gains,
)

__all__ = [
    "Certificate",
    "DesignSpec",
    "DirectionCertificate",
    "GainSchedule",
    "GainsFileError",
    "LMICheck",
    "LMIResult",
    "LPVSystem",
    "ObservabilityReport",
    "ObserverGains",
    "ObserverPlant",
    "ParameterBox",
    "StochasticObservability",
    "StoredCertificate",
    "SynthesisResult",
    "affine_quadratic_stability",
    "analyze_observability",
    "check_design",
    "check_lyapunov",
    "controllability_gramian",
    "design_lpv",
    "frequency_response",
    "frozen_hinf_norm",
    "hinf_performance",
    "load_gains",
    "ltv_observability_matrix",
    "lugre_observer_plant",
    "observability_gramian",
    "plot_frequency_response",
    "save_gains",
    "stochastic_observability",
    "synthesize_observer",
]
