"""Domain exceptions. Each subclasses a built-in so callers may catch either."""

from __future__ import annotations

import importlib
from types import ModuleType


class VestimError(Exception):
    """Base class of every error vestim raises on purpose."""


class LogFormatError(VestimError, ValueError):
    """A drive log violates docs/format.md; the message names column, row and fix."""


class VehicleFileError(VestimError, ValueError):
    """A vehicle TOML file is invalid; the message names the table and key."""


class ManeuverError(VestimError, ValueError):
    """An unknown maneuver or an invalid maneuver option."""


class MissingDependencyError(VestimError, ImportError):
    """An optional extra (``vestim[design]``, ``[logs]``, ``[report]``, ``[batch]``) is not
    installed."""


def optional_import(module: str, extra: str, purpose: str) -> ModuleType:
    """Import ``module`` from the optional extra ``vestim[extra]``, or say how to install it.

    Args:
        module: the module to import, e.g. ``"cvxpy"``.
        extra: the extra that provides it, e.g. ``"design"``.
        purpose: what needs it, for the message, e.g. ``"the LMI tools"``.

    Raises:
        MissingDependencyError: the module is not installed.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{purpose} need(s) {module}, which is not installed; install the extra with "
            f"pip install 'vestim[{extra}]'") from exc


class OutputPathError(VestimError, ValueError):
    """An output path that would overwrite an input or that the writer cannot write."""
