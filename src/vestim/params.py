"""Range checks shared by the stages' parameter dataclasses (SI values, checked on creation)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import fields
from typing import Any


def check_ranges(params: Any, label: str, *, positive: Iterable[str] = (),
                 nonnegative: Iterable[str] = (), finite: bool = False) -> None:
    """Raise :class:`ValueError` naming the first field of the dataclass ``params`` out of its
    range: those in ``positive`` must be > 0, those in ``nonnegative`` ≥ 0 (NaN fails both),
    and with ``finite`` every field must be finite. ``label`` starts the message (the
    stage's name, e.g. "health")."""
    for name in positive:
        if not getattr(params, name) > 0:
            raise ValueError(f"{label} {name} = {getattr(params, name)} must be > 0")
    for name in nonnegative:
        if not getattr(params, name) >= 0:
            raise ValueError(f"{label} {name} = {getattr(params, name)} must be >= 0")
    if finite:
        for f in fields(params):
            if not math.isfinite(getattr(params, f.name)):
                raise ValueError(f"{label} {f.name} = {getattr(params, f.name)} must be finite")
