"""Column names and units of a drive log, defined once (docs/format.md).

Every per-corner channel follows :data:`vestim.constants.CORNERS` order
(fl, fr, rl, rr). Tuples here are the spec's order; :func:`canonical_order`
uses it to lay out the columns of a written log.
"""

from __future__ import annotations

from collections.abc import Iterable

from vestim.constants import CORNERS


def corner_columns(prefix: str) -> list[str]:
    """The four per-corner column names of ``prefix`` in CORNERS order.

    ``corner_columns("omega")`` → ``["omega_fl", "omega_fr", "omega_rl", "omega_rr"]``.
    """
    return [f"{prefix}_{corner}" for corner in CORNERS]


# --- measured channels (what a production car has) -------------------------------------------

T = "t"
WHEEL_SPEEDS: tuple[str, ...] = tuple(corner_columns("omega"))
TORQUES: tuple[str, ...] = tuple(corner_columns("torque"))
IMU: tuple[str, ...] = ("ax", "ay", "az", "yaw_rate", "roll_rate", "pitch_rate")
IMU_REQUIRED: tuple[str, ...] = ("ax", "ay", "yaw_rate")
"""IMU channels every estimator needs; a log may omit ``az``, ``roll_rate``, ``pitch_rate``."""

ROAD_WHEEL_ANGLES: tuple[str, str] = ("delta_fl", "delta_fr")
DELTA = "delta"
"""One road-wheel angle for both front wheels, used when ``delta_fl``/``delta_fr`` are absent."""
STEERING_WHEEL_ANGLE = "steering_wheel_angle"
"""Steering-wheel angle; road-wheel angle = this / ``[vehicle] steering_ratio``."""
STEERING: tuple[str, ...] = (*ROAD_WHEEL_ANGLES, DELTA, STEERING_WHEEL_ANGLE)
"""Every steering column; a log needs delta_fl and delta_fr, or delta, or steering_wheel_angle."""

GNSS_SPEED = "gnss_speed"
"""Speed over ground from a GNSS receiver, m/s (≥ 0), a sparse channel."""
SPARSE: tuple[str, ...] = (GNSS_SPEED,)
"""Channels sampled slower than ``t``: a value on the row nearest each of their own samples
and NaN between (docs/format.md, "Sparse channels")."""

VEHICLE_SPEED = "vehicle_speed"
"""Vehicle speed from the CAN bus (the instrument-cluster / ESC reference speed), m/s (≥ 0),
a dense channel (finite on every row). Not in the spec (proposed by vestim): the velocity
filter uses it only when the log has no wheel speeds."""
SPEED_SOURCES: tuple[str, ...] = (VEHICLE_SPEED, GNSS_SPEED)
"""Speed channels that stand in for the wheel speeds of a log without ``omega_*``."""

MEASURED: tuple[str, ...] = (T, *WHEEL_SPEEDS, *TORQUES, *IMU, *STEERING, *SPARSE,
                             VEHICLE_SPEED)
"""All measured channels in spec order, optional ones (az, roll_rate, pitch_rate, delta,
steering_wheel_angle, gnss_speed, vehicle_speed) included."""

MEASURED_REQUIRED: tuple[str, ...] = (T, "ay", "yaw_rate")
"""Mandatory measured channels apart from steering (which has alternatives, see STEERING)
and the speed (all four ``omega_*``, or one of :data:`SPEED_SOURCES`). ``ax`` is optional
(derived from the speed, see :mod:`vestim.estimators.force.estimator`). The wheel torques
and the wheel speeds are each all four or none: without torques the force stage uses the
chassis equation (:mod:`vestim.models.chassis`)."""

# --- reference channels (ground truth, prefix ``ref_``) ---------------------------------------

REF_PREFIX = "ref_"

STIFFNESS: tuple[str, ...] = ("stiffness_cx_f", "stiffness_cx_r", "stiffness_cy_f",
                              "stiffness_cy_r")
"""Axle-total tire stiffness: cx in N per unit slip ratio, cy in N/rad (``[stiffness]`` keys)."""

_REFERENCE_BASE: tuple[str, ...] = (
    "vx",
    "vy",
    *corner_columns("vx"),
    *corner_columns("vy"),
    *corner_columns("fx"),
    *corner_columns("fy"),
    *corner_columns("fz"),
    *corner_columns("slip_ratio"),
    *corner_columns("slip_angle"),
    *corner_columns("mu"),
    "roll",
    "pitch",
    *STIFFNESS,
)

REFERENCE: tuple[str, ...] = tuple(REF_PREFIX + name for name in _REFERENCE_BASE)
"""Every ``ref_`` column of the spec in its order, then the ``ref_stiffness_*`` extras."""

# --- estimated channels (reference names without the prefix) ----------------------------------

ESTIMATED: tuple[str, ...] = (
    *_REFERENCE_BASE,
    *corner_columns("mu_x"),
    *corner_columns("mu_y"),
)
"""Estimator outputs: reference names without ``ref_``, plus mu_x_* = Fx/Fz and mu_y_* = Fy/Fz."""

MAY_BE_UNKNOWN: tuple[str, ...] = (*corner_columns("mu"), *corner_columns("sigma_mu"))
"""Estimates that are NaN where the data cannot tell them (the road friction potential where
a tire uses too little of it: :mod:`vestim.estimators.friction`); inf is still an error."""

SIGMA_PREFIX = "sigma_"
"""``sigma_<name>`` is the one-sigma uncertainty of ``<name>``, in ``<name>``'s unit."""

KNOWN: tuple[str, ...] = (*MEASURED, *REFERENCE, *ESTIMATED)
"""Every column the spec names, in spec order (t first)."""


def _base_units() -> dict[str, str]:
    units = {T: "s"}
    units.update(dict.fromkeys(WHEEL_SPEEDS, "rad/s"))
    units.update(dict.fromkeys(TORQUES, "N·m"))
    units.update(dict.fromkeys(("ax", "ay", "az"), "m/s²"))
    units.update(dict.fromkeys(("yaw_rate", "roll_rate", "pitch_rate"), "rad/s"))
    units.update(dict.fromkeys(STEERING, "rad"))
    units[GNSS_SPEED] = "m/s"
    units[VEHICLE_SPEED] = "m/s"
    estimated = {"vx": "m/s", "vy": "m/s", "roll": "rad", "pitch": "rad",
                 "stiffness_cx_f": "N", "stiffness_cx_r": "N",
                 "stiffness_cy_f": "N/rad", "stiffness_cy_r": "N/rad"}
    per_corner = {"vx": "m/s", "vy": "m/s", "fx": "N", "fy": "N", "fz": "N",
                  "slip_ratio": "-", "slip_angle": "rad", "mu": "-", "mu_x": "-", "mu_y": "-"}
    for prefix, unit in per_corner.items():
        estimated.update(dict.fromkeys(corner_columns(prefix), unit))
    units.update(estimated)
    units.update({REF_PREFIX + name: unit for name, unit in estimated.items()
                  if name in _REFERENCE_BASE})
    # the pipeline's further outputs (docs/format.md, "Estimated channels")
    units.update(dict.fromkeys((*corner_columns("vxt"), *corner_columns("vyt")), "m/s"))
    units.update({"bias_ax": "m/s²", "cornering_stiffness": "1/rad", "radius_scale": "-",
                  "gnss_latency": "s"})
    units.update(dict.fromkeys((f"mu_{c}_excited" for c in CORNERS), "-"))
    return units


UNITS: dict[str, str] = _base_units()
"""SI unit of every known column ("-" for dimensionless); see :func:`unit_of` for sigma_*
and the flag families of :data:`FLAG_UNITS`."""

FLAG_UNITS: dict[str, str] = {"valid_": "-", "reason_": "-", "health_": "-",
                              "confidence_": "-"}
"""Unit of every column of a flag family, by prefix: ``valid_<group>`` (1/0),
``reason_<group>`` (a bit mask), ``health_<channel>`` (1 healthy, 0 left out) and the
opinion fusion's ``confidence_<corner>`` weights, all dimensionless."""


def unit_of(column: str) -> str | None:
    """Unit of ``column`` (``sigma_<name>`` takes ``<name>``'s unit, a flag family its
    :data:`FLAG_UNITS` entry); ``None`` when unknown."""
    if column in UNITS:
        return UNITS[column]
    if column.startswith(SIGMA_PREFIX):
        return UNITS.get(column[len(SIGMA_PREFIX):])
    return next((u for p, u in FLAG_UNITS.items() if column.startswith(p)), None)


_RANK: dict[str, int] = {}
for _i, _name in enumerate(KNOWN):
    _RANK.setdefault(_name, _i)


def canonical_order(columns: Iterable[str]) -> list[str]:
    """Known columns in spec order (``t`` first), then unknown ones in their given order."""
    cols = list(columns)
    known = sorted((c for c in cols if c in _RANK), key=_RANK.__getitem__)
    return known + [c for c in cols if c not in _RANK]
