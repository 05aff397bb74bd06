"""The registry of estimation methods: every stage's choices, what they are, where their
parameters live.

Each method registers itself next to its code: ``register("fusion", "axle", ...)`` decorates
the method's callable (its kernel or estimator class), which the registry keeps with the
method's integer code and, where it has one, its Params class (:class:`Method`). Everything
that lists or checks methods reads it: the pipeline's config validation
(:class:`vestim.pipeline.PipelineConfig`), ``vestim methods`` (the CLI's list of choices, with
their papers and parameter tables), the conformance suite (``tests/test_conformance.py``),
which runs every registered method, and the pipeline, which builds the corner observer a
velocity method names (``corner``). A new corner observer is its kernel and one
``register("corner", ...)`` with its Params class in :mod:`vestim.estimators.velocity.corner`
(and its branch in ``corner_rows``); a velocity method of another kind also needs its branch,
on its code, in :func:`vestim.pipeline.rows.pipeline_rows`.

Stages (:data:`STAGES`): ``force`` (longitudinal tire force), ``normal`` (load transfer),
``velocity`` (CG and corner velocity) and ``fusion`` (corner estimates to the CG). Two more
kinds (:data:`PARTS`) register the same way without being a pipeline choice of their own:
``corner``, the corner observers a velocity method runs (:attr:`Method.corner`), and
``stiffness``, the batch tire-stiffness estimators of ``vestim stiffness-*``.

Adding a fusion method, for example, is one function of the common signature in
:mod:`vestim.estimators.fusion` under one ``@register("fusion", ...)``; a method the compiled
pipeline runs also needs its branch, on its code, in :mod:`vestim.pipeline.rows`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, TypeVar

from vestim.errors import VestimError

T = TypeVar("T", bound=Callable[..., Any])

STAGES: tuple[str, ...] = ("force", "normal", "velocity", "fusion")
"""The stages with a choice of method, in pipeline order."""

PARTS: tuple[str, ...] = ("corner", "stiffness")
"""The kinds of method that register like a stage but are no pipeline choice of their own:
the corner observers (``corner``) and the batch stiffness estimators (``stiffness``)."""

_FAMILIES = ("vestim.estimators.force", "vestim.estimators.velocity", "vestim.estimators.fusion",
             "vestim.estimators.velocity.corner", "vestim.estimators.stiffness")
"""The packages whose import registers every method (imported on the first lookup)."""


class UnknownMethodError(VestimError, ValueError):
    """A stage or method name that is not registered."""


@dataclass(frozen=True)
class Method:
    """One registered method of a stage.

    Attributes:
        stage: one of :data:`STAGES` or :data:`PARTS`.
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
        params: the class of its parameters (``KFParams``, ``LPVParams``, …), or None.
        impl: the callable that ``register`` decorated (the method's kernel, function or
            estimator class), or None for a method only described here (the velocity and
            normal-load methods, which :mod:`vestim.pipeline.rows` runs by their codes).
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
    params: type | None = None
    impl: Callable[..., Any] | None = None


_REGISTRY: dict[str, dict[str, Method]] = {stage: {} for stage in STAGES + PARTS}


def register(stage: str, name: str, summary: str, *, cite: str = "",
             tables: tuple[str, ...] = (), needs_wheel_speeds: bool = True,
             default: bool = False, corner: str | None = None,
             outputs: tuple[str, ...] = (), params: type | None = None) -> Callable[[T], T]:
    """Register method ``name`` of ``stage`` (see :class:`Method`) with the next code of the
    stage; returns a decorator that records the decorated callable as the method's
    :attr:`~Method.impl` and returns it unchanged.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES` or :data:`PARTS`.
        ValueError: ``name`` is already registered for ``stage``, or a second default; from
            the decorator: a second callable for the method.
    """
    if stage not in _REGISTRY:
        raise UnknownMethodError(f"stage {stage!r}: use one of {', '.join(STAGES + PARTS)}")
    entries = _REGISTRY[stage]
    if name in entries:
        raise ValueError(f"{stage} method {name!r} is registered twice")
    if default and any(m.default for m in entries.values()):
        raise ValueError(f"{stage} has two default methods ({name!r} and "
                         f"{next(m.name for m in entries.values() if m.default)!r})")
    entries[name] = Method(stage, name, summary, cite, tuple(tables), needs_wheel_speeds,
                           default, corner, len(entries), tuple(outputs), params)

    def decorate(obj: T) -> T:
        if entries[name].impl is not None:
            raise ValueError(f"{stage} method {name!r} already has its callable "
                             f"{entries[name].impl!r}; register it once")
        entries[name] = replace(entries[name], impl=obj)
        return obj

    return decorate


def registered(stage: str) -> dict[str, Method]:
    """The methods of ``stage`` registered so far, by name in registration order (their
    codes' order), without importing the method families: what a module that registers its
    methods reads their codes from, right after its ``register`` calls.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES` or :data:`PARTS`.
    """
    return dict(_REGISTRY[_kind(stage)])


def _loaded() -> dict[str, dict[str, Method]]:
    for module in _FAMILIES:
        importlib.import_module(module)
    return _REGISTRY


def _kind(stage: object) -> str:
    """``stage`` if it is one of :data:`STAGES` or :data:`PARTS`, else UnknownMethodError."""
    if not isinstance(stage, str) or stage not in _REGISTRY:
        raise UnknownMethodError(f"stage {stage!r}: use one of {', '.join(STAGES + PARTS)}")
    return stage


def lookup_stage(stage: object) -> str:
    """``stage`` if it is one of :data:`STAGES`.

    Raises:
        UnknownMethodError: it is not; the message lists the stages.
    """
    if not isinstance(stage, str) or stage not in STAGES:
        raise UnknownMethodError(f"stage {stage!r}: use one of {', '.join(STAGES)}")
    return stage


def methods(stage: str) -> tuple[Method, ...]:
    """The registered methods of ``stage`` (a stage or one of :data:`PARTS`), the default
    first, then in registration order.

    Raises:
        UnknownMethodError: ``stage`` is not one of :data:`STAGES` or :data:`PARTS`.
    """
    entries = list(_loaded()[_kind(stage)].values())
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
