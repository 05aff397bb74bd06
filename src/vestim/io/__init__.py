"""Reading and writing drive logs and vehicle files (``shared/spec/log-format.md``)."""

from vestim.io.log import read_log, road_wheel_angles, validate_log, write_log
from vestim.io.sanity import Finding, check_log
from vestim.io.vehicle import Vehicle, load_vehicle

__all__ = ["Finding", "Vehicle", "check_log", "load_vehicle", "read_log", "road_wheel_angles",
           "validate_log", "write_log"]
