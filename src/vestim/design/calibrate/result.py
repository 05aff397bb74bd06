"""One identified value of ``vestim calibrate`` (the type lives with the file format, in
:mod:`vestim.io.calibration`, because the vehicle loader reads it back)."""

from vestim.io.calibration import Identified

__all__ = ["Identified"]
