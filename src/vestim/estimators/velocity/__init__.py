"""Velocity estimators: reference-speed filter, kinematic baseline, tire-model corner observers."""
