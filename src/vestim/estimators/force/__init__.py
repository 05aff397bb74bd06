"""Tire forces per corner without road friction: longitudinal, lateral, normal (001 Sec. III)."""

from vestim.estimators.force.estimator import ForceConfig, ForceEstimator

__all__ = ["ForceConfig", "ForceEstimator"]
