"""Tests of the tire-stiffness estimators (002)."""
