"""The pipeline's configuration: which method runs each stage, and every stage's parameters.

:class:`PipelineConfig` is what ``vestim estimate`` builds from its flags or from the
``[pipeline]`` table of a TOML file.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from vestim.errors import VestimError
from vestim.estimators.force.longitudinal import METHODS as FORCE_METHODS
from vestim.estimators.friction import FrictionParams
from vestim.estimators.fusion import FUSION_METHODS, FusionParams
from vestim.estimators.health import HealthParams, ImuHealthParams
from vestim.estimators.uncertainty import UncertaintyParams
from vestim.estimators.validity import ValidityParams
from vestim.estimators.velocity.lpv_observer import GainSchedule as LPVGains
from vestim.estimators.velocity.lpv_observer import LPVParams
from vestim.estimators.velocity.reference import RadiusParams, ReferenceParams, StiffnessParams

VELOCITY_METHODS: tuple[str, ...] = ("fused", "reference", "kinematic", "kf", "ukf", "lpv")


class PipelineConfigError(VestimError, ValueError):
    """An unknown stage name or option in a pipeline configuration."""


@dataclass(frozen=True)
class PipelineConfig:
    """Which module runs each stage, and its parameters.

    Attributes:
        force: longitudinal force method (see :mod:`vestim.estimators.force.longitudinal`).
        normal: elastic load transfer, "dynamic" or "static".
        velocity: "reference" (default: the ABS/ESC-style filter), "fused" (the reference
            filter with the LuGre KF corner estimates as extra measurements), "kinematic"
            (000 eq. (15)), or a corner observer mapped to the CG by the fusion stage:
            "kf" (000 eq. (16)–(23)), "ukf" (003 Alg. 1), "lpv" (001 eq. (22)–(24),
            (36)–(38)).
        fusion: how the four corner observers' estimates, mapped to the CG, become one
            (:mod:`vestim.estimators.fusion`): "axle" (fixed η1 = η2 = 0.5), "adaptive"
            (001 eq. (34)–(35)), "opinion" (003 eq. (5)–(13); writes ``confidence_*``).
            Used by the corner methods and by "fused" for its corner measurement.
        reference: parameters of the reference filter.
        cornering: the online cornering-stiffness regression of its v_y bounds.
        radius: the online wheel-radius scale from ``gnss_speed`` (logs that have it).
        fusion_params: parameters of the fusion stage.
        friction: the road-friction-potential stage (:mod:`vestim.estimators.friction`).
        validity: thresholds of the validity flags (:mod:`vestim.estimators.validity`).
        health: thresholds of the wheel-speed health test (:mod:`vestim.estimators.health`).
        imu_health: thresholds of the IMU health test (:mod:`vestim.estimators.health.imu`).
        uncertainty: the σ models of every channel (:mod:`vestim.estimators.uncertainty`).
        gains: path of a gains file from ``vestim design lpv`` for the "lpv" observers
            (default: 001's constant gains).
    """

    force: str = "ukf"
    normal: str = "static"
    velocity: str = "fused"
    fusion: str = "axle"
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    cornering: StiffnessParams = field(default_factory=StiffnessParams)
    radius: RadiusParams = field(default_factory=RadiusParams)
    fusion_params: FusionParams = field(default_factory=FusionParams)
    friction: FrictionParams = field(default_factory=FrictionParams)
    validity: ValidityParams = field(default_factory=ValidityParams)
    health: HealthParams = field(default_factory=HealthParams)
    imu_health: ImuHealthParams = field(default_factory=ImuHealthParams)
    uncertainty: UncertaintyParams = field(default_factory=UncertaintyParams)
    gains: str | None = None

    def __post_init__(self) -> None:
        if self.force not in FORCE_METHODS:
            raise PipelineConfigError(f"force method {self.force!r}: use one of "
                                      f"{', '.join(FORCE_METHODS)}")
        if self.velocity not in VELOCITY_METHODS:
            raise PipelineConfigError(f"velocity method {self.velocity!r}: use one of "
                                      f"{', '.join(VELOCITY_METHODS)}")
        if self.fusion not in FUSION_METHODS:
            raise PipelineConfigError(f"fusion method {self.fusion!r}: use one of "
                                      f"{', '.join(FUSION_METHODS)}")
        if self.gains is not None and not isinstance(self.gains, str):
            raise PipelineConfigError(f"gains = {self.gains!r}: the path of a gains file "
                                      "(a string) from `vestim design lpv`")
        for name in ("force", "normal", "velocity", "fusion"):
            if not isinstance(getattr(self, name), str):
                raise PipelineConfigError(f"{name} = {getattr(self, name)!r} must be a string")
        if self.normal not in ("dynamic", "static"):
            raise PipelineConfigError(f"normal-load mode {self.normal!r}: use dynamic or static")

    @classmethod
    def from_toml(cls, path: str | Path) -> PipelineConfig:
        """Read the ``[pipeline]`` table of a TOML file (keys: force, normal, velocity, fusion,
        gains)."""
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        table = data.get("pipeline")
        if not isinstance(table, dict):
            raise PipelineConfigError(f"{path}: no [pipeline] table")
        allowed = {f.name for f in fields(cls)} - {"reference", "fusion_params", "cornering",
                                                "radius", "friction", "validity",
                                                "health", "imu_health", "uncertainty"}
        unknown = sorted(set(table) - allowed)
        if unknown:
            raise PipelineConfigError(f"{path}: [pipeline] has unknown key(s) {', '.join(unknown)};"
                                      f" allowed: {', '.join(sorted(allowed))}")
        return cls(**table)


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
