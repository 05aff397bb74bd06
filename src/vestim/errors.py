"""Domain exceptions. Each subclasses a built-in so callers may catch either."""


class VestimError(Exception):
    """Base class of every error vestim raises on purpose."""


class LogFormatError(VestimError, ValueError):
    """A drive log violates ``shared/spec/log-format.md``; the message names column, row and fix."""


class VehicleFileError(VestimError, ValueError):
    """A vehicle TOML file is invalid; the message names the table and key."""


class ManeuverError(VestimError, ValueError):
    """An unknown maneuver or an invalid maneuver option."""
