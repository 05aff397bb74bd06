"""Tire forces per corner without road friction: longitudinal, lateral, normal (001 Sec. III)."""

from vestim.estimators.force.estimator import ForceConfig, ForceEstimator

# The methods register next to their code: the "force" stage's in
# vestim.estimators.force.longitudinal, the "normal" stage's in vestim.estimators.force.normal.

__all__ = ["ForceConfig", "ForceEstimator"]
