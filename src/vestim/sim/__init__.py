"""Ground-truth simulator: double-track plant, maneuver library, sensor models."""

from vestim.sim.maneuvers import DEFAULT_SET, Maneuver, get_maneuver, maneuver_names
from vestim.sim.road import Road
from vestim.sim.sensors import SensorModel
from vestim.sim.simulate import simulate

__all__ = ["DEFAULT_SET", "Maneuver", "Road", "SensorModel", "get_maneuver", "maneuver_names",
           "simulate"]
