"""Shared helpers for simulator tests: custom maneuvers with ideal sensors."""

import numpy as np
import pytest

from vestim.io import load_vehicle
from vestim.sim import Road, SensorModel, simulate
from vestim.sim.maneuvers import Maneuver


def const(value: float):
    return lambda t: np.full_like(t, value)


def run(road: Road, *, duration: float = 4.0, v0: float = 15.0, speed: float | None = None,
        swa=None, throttle=None, brake=None, tire: str = "magic", **kw):
    """Simulate a custom maneuver with ideal sensors on the SUV."""
    zero = const(0.0)
    m = Maneuver("custom", "test", duration, v0, swa or zero, throttle or zero, brake or zero,
                 const(speed) if speed is not None else const(np.nan), road, tire=tire, **kw)
    return simulate(m, SUV, sensors=SensorModel.ideal())


SUV = load_vehicle("hashemi_suv")


@pytest.fixture(scope="session")
def suv():
    return SUV
