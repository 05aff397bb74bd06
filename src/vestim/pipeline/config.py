"""The pipeline's configuration: which method runs each stage, and every stage's parameters.

:class:`PipelineConfig` is what ``vestim estimate`` builds from its flags or from the
``[pipeline]`` table of a TOML file.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from types import UnionType
from typing import Any, Union, get_args, get_origin, get_type_hints

from vestim.errors import VestimError
from vestim.estimators import registry
from vestim.estimators.force import ForceConfig
from vestim.estimators.friction import FrictionParams
from vestim.estimators.fusion import FusionParams
from vestim.estimators.health import HealthParams, ImuHealthParams
from vestim.estimators.uncertainty import UncertaintyParams
from vestim.estimators.validity import ValidityParams
from vestim.estimators.velocity.lpv_observer import GainSchedule as LPVGains
from vestim.estimators.velocity.lpv_observer import LPVParams
from vestim.estimators.velocity.lugre_kf import KFParams
from vestim.estimators.velocity.reference import RadiusParams, ReferenceParams, StiffnessParams
from vestim.io.calibration import toml_value

VELOCITY_METHODS: tuple[str, ...] = registry.names("velocity")
"""The registered velocity methods, the default first (:mod:`vestim.estimators.registry`)."""

_STAGE_FIELDS = {"force": "force", "normal": "normal", "velocity": "velocity", "fusion": "fusion"}
"""PipelineConfig's method fields and the registry stage each selects from."""


class PipelineConfigError(VestimError, ValueError):
    """An unknown stage name or option in a pipeline configuration."""


def _default(stage: str) -> Any:
    return field(default_factory=lambda: registry.default(stage))


@dataclass(frozen=True)
class PipelineConfig:
    """Which method runs each stage, and every stage's parameters.

    The method fields take a name registered for their stage
    (:mod:`vestim.estimators.registry`; ``vestim methods`` lists them with their papers);
    their defaults are the registry's. Every other field is a parameter table: a validated
    dataclass that a TOML file sets as ``[pipeline.<field>]`` (:meth:`from_toml`).

    Attributes:
        force: longitudinal force method (default "ukf").
        normal: elastic load transfer, "static" (default) or "dynamic".
        velocity: CG velocity method (default "reference": the reference filter; "fused" it
            with the LuGre KF corner estimates as extra measurements in all-wheel slip,
            "kinematic", or a corner observer mapped to the CG by the fusion stage: "kf",
            "ukf", "lpv").
        fusion: how the four corner observers' estimates, mapped to the CG, become one
            (default "axle"; "adaptive", "opinion", which writes ``confidence_*``). Used by the
            corner methods and by "fused" for its corner measurement.
        force_params: the force stage's parameters (:class:`~vestim.estimators.force.ForceConfig`:
            the longitudinal observers' ``ukf`` / ``pid`` / ``uio`` tables, the ``lateral``
            UKF, the attitude filter); its ``longitudinal`` and ``normal`` come from ``force`` and
            ``normal``.
        reference: parameters of the reference filter.
        cornering: the online cornering-stiffness regression of its v_y bounds.
        radius: the online wheel-radius scale from ``gnss_speed`` (logs that have it).
        corner: the LuGre corner observers of "kf", "ukf" and "fused" (001 eq. (16)–(23)).
        fusion_params: parameters of the fusion stage.
        friction: the road-friction-potential stage (:mod:`vestim.estimators.friction`).
        validity: thresholds of the validity flags (:mod:`vestim.estimators.validity`).
        health: thresholds of the wheel-speed health test (:mod:`vestim.estimators.health`).
        imu_health: thresholds of the IMU health test (:mod:`vestim.estimators.health.imu`).
        uncertainty: the σ models of every channel (:mod:`vestim.estimators.uncertainty`).
        gains: path of a gains file from ``vestim design lpv`` for the "lpv" observers
            (default: 001's constant gains).
    """

    force: str = _default("force")
    normal: str = _default("normal")
    velocity: str = _default("velocity")
    fusion: str = _default("fusion")
    force_params: ForceConfig = field(default_factory=ForceConfig)
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    cornering: StiffnessParams = field(default_factory=StiffnessParams)
    radius: RadiusParams = field(default_factory=RadiusParams)
    corner: KFParams = field(default_factory=KFParams)
    fusion_params: FusionParams = field(default_factory=FusionParams)
    friction: FrictionParams = field(default_factory=FrictionParams)
    validity: ValidityParams = field(default_factory=ValidityParams)
    health: HealthParams = field(default_factory=HealthParams)
    imu_health: ImuHealthParams = field(default_factory=ImuHealthParams)
    uncertainty: UncertaintyParams = field(default_factory=UncertaintyParams)
    gains: str | None = None

    def __post_init__(self) -> None:
        for name, stage in _STAGE_FIELDS.items():
            try:
                registry.lookup(stage, getattr(self, name))
            except registry.UnknownMethodError as exc:
                raise PipelineConfigError(str(exc)) from None
        if self.gains is not None and not isinstance(self.gains, str):
            raise PipelineConfigError(f"gains = {self.gains!r}: the path of a gains file "
                                      "(a string) from `vestim design lpv`")
        for f in fields(self):
            if f.name in PARAMETER_TABLES and not isinstance(getattr(self, f.name),
                                                              PARAMETER_TABLES[f.name]):
                raise PipelineConfigError(
                    f"{f.name} = {getattr(self, f.name)!r}: must be a "
                    f"{PARAMETER_TABLES[f.name].__name__}")

    def force_config(self) -> ForceConfig:
        """The force stage's config: :attr:`force_params` with this config's methods."""
        return replace(self.force_params, longitudinal=self.force, normal=self.normal)

    @classmethod
    def from_toml(cls, path: str | Path) -> PipelineConfig:
        """Read the ``[pipeline]`` table of a TOML file.

        Its keys ``force``, ``normal``, ``velocity``, ``fusion`` name the methods and ``gains``
        is a gains file; its sub-tables ``[pipeline.<table>]`` (one per parameter field of this
        class: ``[pipeline.reference]``, ``[pipeline.force_params.ukf]``, …) set parameters,
        any not given keeping its default. Values are checked against the field's type
        (a number where a float is expected, a list of numbers for a tuple) and then by the
        table's own validation.

        Raises:
            PipelineConfigError: no ``[pipeline]`` table, an unknown key or table (the message
                lists the allowed ones), a value of the wrong type, or a value out of range; the
                message names the file, the table and the key.
            OSError: the file cannot be read.
        """
        try:
            data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise PipelineConfigError(f"{path}: not valid TOML ({exc})") from None
        table = data.get("pipeline")
        if not isinstance(table, dict):
            raise PipelineConfigError(f"{path}: no [pipeline] table")
        try:
            values = _values(cls, table, "pipeline")
            return cls(**values)
        except PipelineConfigError as exc:
            raise PipelineConfigError(f"{path}: {exc}") from None


    def to_toml(self) -> str:
        """This config as a TOML ``[pipeline]`` table and its parameter tables, every field
        written (:meth:`from_toml` of the text gives this config back); ``vestim config``
        prints the defaults this way, for a user to edit."""
        lines = ["[pipeline]"]
        tables: list[tuple[str, Any]] = []
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in PARAMETER_TABLES:
                tables.append((f"pipeline.{f.name}", value))
            elif value is not None:
                lines.append(f"{f.name} = {toml_value(value)}")
        for where, value in tables:
            lines += _toml_table(where, value)
        return "\n".join(lines) + "\n"


def _toml_table(where: str, obj: Any) -> list[str]:
    """``[where]`` with the plain fields of dataclass ``obj``, then its nested tables."""
    lines = ["", f"[{where}]"]
    nested: list[tuple[str, Any]] = []
    for f in fields(obj):
        if (type(obj), f.name) in _NOT_IN_TOML:
            continue
        value = getattr(obj, f.name)
        if is_dataclass(value):
            nested.append((f"{where}.{f.name}", value))
        elif value is not None:  # None: the field's default, which TOML cannot spell
            lines.append(f"{f.name} = {toml_value(value)}")
    for w, value in nested:
        lines += _toml_table(w, value)
    return lines


PARAMETER_TABLES: dict[str, type] = {
    "force_params": ForceConfig, "reference": ReferenceParams, "cornering": StiffnessParams,
    "radius": RadiusParams, "corner": KFParams, "fusion_params": FusionParams,
    "friction": FrictionParams, "validity": ValidityParams, "health": HealthParams,
    "imu_health": ImuHealthParams, "uncertainty": UncertaintyParams}
"""The parameter fields of :class:`PipelineConfig` and their dataclasses (``[pipeline.<name>]``)."""

_NOT_IN_TOML: dict[tuple[type, str], str] = {
    (ForceConfig, "longitudinal"): "set it with force = … in [pipeline]",
    (ForceConfig, "normal"): "set it with normal = … in [pipeline]"}
"""Fields a table may not set, and where they are set instead."""


def _values(cls: type, table: dict[str, Any], where: str) -> dict[str, Any]:
    """The keyword arguments of dataclass ``cls`` from the TOML ``table`` at ``[where]``."""
    hints = get_type_hints(cls)
    allowed = [f.name for f in fields(cls) if (cls, f.name) not in _NOT_IN_TOML]
    out: dict[str, Any] = {}
    for key, value in table.items():
        if (cls, key) in _NOT_IN_TOML:
            raise PipelineConfigError(f"[{where}] {key}: {_NOT_IN_TOML[cls, key]}")
        if key not in allowed:
            raise PipelineConfigError(f"[{where}] has unknown key {key!r}; allowed: "
                                      f"{', '.join(allowed)}")
        if cls is PipelineConfig and key not in PARAMETER_TABLES:
            out[key] = value  # a method name or the gains path: __post_init__ says what is wrong
        else:
            out[key] = _convert(hints[key], value, f"{where}.{key}")
    if cls is not PipelineConfig:
        try:
            cls(**out)
        except (ValueError, TypeError) as exc:
            raise PipelineConfigError(f"[{where}]: {exc}") from None
    return out


def _convert(hint: Any, value: Any, where: str) -> Any:
    """``value`` from TOML as the field type ``hint`` (float, int, bool, str, tuples of those,
    a nested dataclass from a table, ``X | None``)."""
    if is_dataclass(hint) and isinstance(hint, type):
        if not isinstance(value, dict):
            raise PipelineConfigError(f"{where} = {value!r}: expected a table [{where}]")
        return hint(**_values(hint, value, where))
    origin, args = get_origin(hint), get_args(hint)
    if origin in (Union, UnionType):
        options = [a for a in args if a is not type(None)]
        errors = []
        for option in options:
            try:
                return _convert(option, value, where)
            except PipelineConfigError as exc:
                errors.append(str(exc))
        raise PipelineConfigError(errors[0])
    if origin is tuple:
        if not isinstance(value, list):
            raise PipelineConfigError(f"{where} = {value!r}: expected a list")
        kinds = [args[0]] * len(value) if len(args) == 2 and args[1] is Ellipsis else list(args)
        if len(kinds) != len(value):
            raise PipelineConfigError(f"{where} = {value!r}: expected {len(kinds)} values")
        return tuple(_convert(k, v, f"{where}[{i}]") for i, (k, v) in
                     enumerate(zip(kinds, value, strict=True)))
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise PipelineConfigError(f"{where} = {value!r}: expected a number")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise PipelineConfigError(f"{where} = {value!r}: expected an integer")
        return value
    if hint in (bool, str):
        if not isinstance(value, hint):
            raise PipelineConfigError(f"{where} = {value!r}: expected a {hint.__name__}")
        return value
    raise PipelineConfigError(f"{where}: a field of type {hint} cannot be set from TOML")


def _lpv_params_from_gains(path: str) -> LPVParams:
    """LPV observer parameters from a gains file of ``vestim design lpv`` (innovation form)."""
    from vestim.estimators.velocity.lpv_gains import load_gains

    schedule = load_gains(path)

    def one(g: Any) -> LPVGains | None:
        return None if g is None else LPVGains(tuple(g.omega), tuple(g.l1), tuple(g.l2),
                                               "innovation")

    lon = one(schedule.longitudinal)
    if lon is None:
        raise PipelineConfigError(f"{path}: the gains file has no [longitudinal] table")
    return LPVParams(longitudinal=lon, lateral=one(schedule.lateral))
