"""Reading and writing drive logs and vehicle files (docs/format.md)."""

from vestim.io.log import (
    LogWriter,
    iter_log,
    parquet_rows,
    read_log,
    road_wheel_angles,
    validate_log,
    write_log,
)
from vestim.io.sanity import Finding, check_log
from vestim.io.vehicle import Vehicle, load_vehicle

__all__ = ["Finding", "LogWriter", "Vehicle", "check_log", "iter_log", "load_vehicle",
           "parquet_rows", "read_log", "road_wheel_angles", "validate_log", "write_log"]
