"""Physical constants used across vestim (defined once)."""

G = 9.81
"""Gravitational acceleration in m/s² (the spec's at-rest ``az`` reading)."""

CORNERS: tuple[str, str, str, str] = ("fl", "fr", "rl", "rr")
"""Corner order used by every array with a corner axis: front-left, front-right, rear-left, rear-right."""
