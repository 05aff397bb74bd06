"""The stages' parameters: range checks of the config dataclasses (SI values, checked on
creation) and the one packer that turns a config into a kernel's ``Params`` NamedTuple."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import fields
from typing import Any, NamedTuple, TypeVar, get_type_hints

T = TypeVar("T", bound=NamedTuple)


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


def pack(kind: type[T], config: Any = None, **values: Any) -> T:
    """The compiled kernels' parameters: the NamedTuple ``kind`` filled field by field.

    Each field of ``kind`` takes ``values[name]`` where given (derived quantities: the vehicle's
    geometry, a stiffness prior), else the attribute of the same name of ``config`` (the stage's
    validated dataclass). A field whose annotation is ``float`` is stored as a Python float
    and one annotated ``bool`` or ``int`` as that type (a kernel's NamedTuple argument then
    has one Numba type whatever the config held); other fields (arrays, nested NamedTuples)
    are stored as given.

    Raises:
        TypeError: a field of ``kind`` is neither in ``values`` nor an attribute of
            ``config`` (a programming error: the kernel asks for a parameter no one sets).
    """
    unknown = set(values) - set(kind._fields)
    if unknown:
        raise TypeError(f"{kind.__name__} has no field(s) {', '.join(sorted(unknown))}")
    hints = get_type_hints(kind)
    args = []
    for name in kind._fields:
        if name in values:
            v = values[name]
        elif config is not None and hasattr(config, name):
            v = getattr(config, name)
        else:
            raise TypeError(f"{kind.__name__}.{name}: not given and not a field of "
                            f"{type(config).__name__}")
        hint = hints.get(name)
        args.append(hint(v) if hint in (float, bool, int) else v)
    return kind(*args)
