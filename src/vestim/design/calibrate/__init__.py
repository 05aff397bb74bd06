"""``vestim calibrate``: identify the car's sensors, body and tires from its own logs (issue 13)."""

from vestim.design.calibrate.result import Identified

__all__ = ["Identified"]
