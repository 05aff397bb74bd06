"""The registry of estimation methods: every stage's choices, what they are, where their
parameters live.

Each method registers itself next to its code (``register("velocity", "kf", ...)`` decorating
its estimator), and everything that lists or checks methods reads it: the pipeline's config
validation (:class:`vestim.pipeline.PipelineConfig`), ``vestim methods`` (the CLI's list of
choices, with their papers and parameter tables) and the conformance suite
(``tests/test_conformance.py``), which runs every registered method, and the pipeline, which
builds the corner observer a velocity method names (``corner``). A new corner observer is a
method of :class:`~vestim.estimators.velocity.corner.CornerVelocityEstimator` and one
``register`` call; a velocity method of another kind also needs its branch, on its code, in
:func:`vestim.pipeline.rows.pipeline_rows`.

Stages (:data:`STAGES`): ``force`` (longitudinal tire force), ``normal`` (load transfer),
``velocity`` (CG and corner velocity) and ``fusion`` (corner estimates to the CG).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from vestim.errors import VestimError

T = TypeVar("T")

STAGES: tuple[str, ...] = ("force", "normal", "velocity", "fusion")
"""The stages with a choice of method, in pipeline order."""

_FAMILIES = ("vestim.estimators.force", "vestim.estimators.velocity", "vestim.estimators.fusion")
"""The packages whose import registers every method (imported on the first lookup)."""


class UnknownMethodError(VestimError, ValueError):
    """A stage or method name that is not registered."""


@dataclass(frozen=True)
class Method:
    """One registered method of a stage.

    Attributes:
        stage: one of :data:`STAGES`.
        name: the name a config or the CLI selects it by.
        summary: one line saying what it does (the CLI's help).
        cite: the papers' equations it implements ("001 eq. (22)–(24)"), or "" for ours.
        tables: the ``[pipeline.<table>]`` TOML tables (fields of ``PipelineConfig``) that hold
            its parameters, in the order they apply.
        needs_wheel_speeds: it cannot run on a log without ``omega_*``.
        default: the stage's default method.
        corner: for a velocity method, the corner observer it runs
            (:class:`~vestim.estimators.velocity.corner.CornerVelocityEstimator`'s method), or
            None.
        code: its integer code, the order of registration within the stage: what the
            compiled pipeline (:mod:`vestim.pipeline.rows`) dispatches on.
        outputs: the optional output families it writes (``"sigma_fx"``: a σ of F_x;
            ``"sigma_v"``: a filter σ of the velocity; ``"bias_ax"``: an accelerometer bias;
            ``"confidence"``: per-corner confidences), which set the estimate's columns.
    """

    stage: str
    name: str
    summary: str
    cite: str = ""
    tables: tuple[str, ...] = ()
    needs_wheel_speeds: bool = True
    default: bool = False
    corner: str | None = None
    code: int = 0
    outputs: tuple[str, ...] = ()


_REGISTRY: dict[str, dict[str, Method]] = {stage: {} for stage in STAGES}


def register(stage: str, name: str, summary: str, *, cite: str = "",
             tables: tuple[str, ...] = (), needs_wheel_speeds: bool = True,
             default: bool = False, corner: str | None = None,
             outputs: tuple[str, ...] = ()) -> Callable[[T], T]:
    """Register method ``name`` of ``stage`` (see :class:`Method`); returns a decorator that
    leaves the decorated estimator unchanged.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES`.
        ValueError: ``name`` is already registered for ``stage``, or a second default.
    """
    if stage not in _REGISTRY:
        raise UnknownMethodError(f"stage {stage!r}: use one of {', '.join(STAGES)}")
    entries = _REGISTRY[stage]
    if name in entries:
        raise ValueError(f"{stage} method {name!r} is registered twice")
    if default and any(m.default for m in entries.values()):
        raise ValueError(f"{stage} has two default methods ({name!r} and "
                         f"{next(m.name for m in entries.values() if m.default)!r})")
    entries[name] = Method(stage, name, summary, cite, tuple(tables), needs_wheel_speeds,
                           default, corner, len(entries), tuple(outputs))

    def decorate(obj: T) -> T:
        return obj

    return decorate


def registered(stage: str) -> dict[str, Method]:
    """The methods of ``stage`` registered so far, by name in registration order (their
    codes' order), without importing the method families: what a module that registers its
    methods reads their codes from, right after its ``register`` calls.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES`.
    """
    return dict(_REGISTRY[lookup_stage(stage)])


def _loaded() -> dict[str, dict[str, Method]]:
    for module in _FAMILIES:
        importlib.import_module(module)
    return _REGISTRY


def lookup_stage(stage: object) -> str:
    """``stage`` if it is one of :data:`STAGES`.

    Raises:
        UnknownMethodError: it is not; the message lists the stages.
    """
    if not isinstance(stage, str) or stage not in STAGES:
        raise UnknownMethodError(f"stage {stage!r}: use one of {', '.join(STAGES)}")
    return stage


def methods(stage: str) -> tuple[Method, ...]:
    """The registered methods of ``stage``, the default first, then in registration order.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES`.
    """
    entries = list(_loaded()[lookup_stage(stage)].values())
    return tuple(sorted(entries, key=lambda m: not m.default))


def names(stage: str) -> tuple[str, ...]:
    """The names of :func:`methods` of ``stage``."""
    return tuple(m.name for m in methods(stage))


def default(stage: str) -> str:
    """The name of the default method of ``stage``."""
    first = methods(stage)[0]
    if not first.default:
        raise UnknownMethodError(f"stage {stage!r} has no default method registered")
    return first.name


def lookup(stage: str, name: object) -> Method:
    """The registered method ``name`` of ``stage``.

    Raises:
        UnknownMethodError: not registered; the message lists the choices.
    """
    entries = {m.name: m for m in methods(stage)}
    if not isinstance(name, str) or name not in entries:
        raise UnknownMethodError(f"{stage} method {name!r}: use one of {', '.join(entries)} "
                                 "(`vestim methods` describes them)")
    return entries[name]
