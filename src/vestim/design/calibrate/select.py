"""Calibration that never hurts: which identified values the estimators use (issue 31).

A value :func:`vestim.calibrate` identified replaces the vehicle file's nominal value only
where two tests both say the nominal value is wrong and the identified one generalises:

1. **Significance.** ``|value − nominal| > K_SIGMA·σ``: the logs show the nominal value is
   off by more than their own uncertainty. Within that band replacing it only adds noise.
2. **Held-out residuals.** Leave-one-out over the calibration logs (a single log: over its
   two halves): for each fold i the value identified *without* log i, θ₋ᵢ, and the one
   identified from log i alone, θ̂ᵢ ± σᵢ. Each identification is a least-squares fit, so
   log i's residual sum of squares at a value θ exceeds its minimum by
   ((θ − θ̂ᵢ)/σᵢ)² (the fit's quadratic form, with σᵢ its standard error). The candidate is
   kept only if Σᵢ ((θ₋ᵢ − θ̂ᵢ)/σᵢ)² < Σᵢ ((θ_nom − θ̂ᵢ)/σᵢ)²: over the logs it was not
   fitted on, the identification predicts the data better than the nominal value does. A
   value learnt from one manoeuvre that does not hold on the car's other drives (a sine
   steer's cornering stiffness, a steering ratio from one slalom) fails here. A fold in
   which θ₋ᵢ was not excited uses the nominal value (what the estimators would use), so a
   value that only one log excites has no held-out evidence and is not used.

One value can also reach the estimators through another: the Pipeline's cornering-stiffness
prior is the calibrated ``cy_f + cy_r`` when both are used, else the ``[tire]`` table's
σ0y/κy. The LuGre lateral values ``sigma0_y`` and ``kappa_y`` are therefore used only
together with ``cy_f`` and ``cy_r`` (:func:`couple`): otherwise a LuGre fit would move the
prior that the direct identification was refused for (on the campaign's s1_021, κ_y 4.0
against 12 made the prior 3× stiffer and v_y 0.090 → 0.185 m/s).

A value without a nominal (``gnss_latency``, ``understeer_gradient``: reported only) is not
tested. The decision is stated in the calibrated file (``used_<key>``, ``decision_<key>``)
and in the report. The thresholds are fixed (``K_SIGMA``); nothing is tuned per log.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from vestim.constants import G
from vestim.io.calibration import LUGRE_KEYS, Identified
from vestim.io.vehicle import Vehicle

K_SIGMA = 2.0
"""How many σ an identified value must lie from the nominal one to replace it: two σ is the
95 % two-sided test that the nominal value is consistent with the logs."""


@dataclass(frozen=True)
class Fold:
    """One held-out fold: the value identified without the fold (``train``) and from the
    fold alone (``held``), each None where that identification did not return the key."""

    train: Identified | None
    held: Identified | None


def nominal_values(vehicle: Vehicle) -> dict[str, float]:
    """What the estimators use for each calibration key when the file has no calibrated
    value: the vehicle file's (or its defaults') value, in the key's SI unit.

    Keys the estimators only report (``gnss_latency``, ``understeer_gradient``, μ_s, μ_c,
    v_s) have none.
    """
    from vestim.estimators.friction.potential import FrictionParams, corner_kx

    b, t, s = vehicle.body, vehicle.tire, vehicle.suspension
    out: dict[str, float] = {f"radius_{c}": b.wheel_radius for c in ("fl", "fr", "rl", "rr")}
    out.update({"radius_scale": 1.0, "accel_scale": 1.0, "steering_ratio": b.steering_ratio,
                "steering_offset": 0.0})
    out.update({f"bias_{a}": 0.0 for a in ("ax", "ay", "az", "yaw_rate", "roll_rate",
                                           "pitch_rate")})
    out.update({f"mount_{a}": 0.0 for a in ("roll", "pitch", "yaw")})
    # the force estimator's quasi-static attitude gradients (ForceEstimator.__init__)
    out["roll_gradient"] = b.mass * (b.cg_height - b.roll_center_height) / s.roll_stiffness
    out["pitch_gradient"] = b.mass * (b.cg_height - s.pitch_center_height) / s.pitch_stiffness
    out.update({k: getattr(t, k) for k in LUGRE_KEYS if k not in ("mu_s", "mu_c", "v_s")})
    wheelbase = b.lf + b.lr
    front, rear = b.mass * G * b.lr / wheelbase, b.mass * G * b.lf / wheelbase
    # the Pipeline's cornering-stiffness prior per unit load, σ0y/κy, on the static loads
    per_load = t.sigma0_y / t.kappa_y
    out.update({"cy_f": per_load * front, "cy_r": per_load * rear})
    kx = corner_kx(replace(vehicle, calibration=None), FrictionParams())
    out.update({"cx_f": float(kx[0]) * front, "cx_r": float(kx[2]) * rear})
    return out


def decide(key: str, value: Identified, nominal: float | None, folds: Sequence[Fold],
           *, k_sigma: float = K_SIGMA) -> Identified:
    """``value`` with ``used`` and ``decision`` set by the two tests of the module docstring.

    Args:
        key: the calibration key (for the text).
        value: the value identified from all calibration logs.
        nominal: the value the estimators use without it (:func:`nominal_values`); None: the
            key is reported only and is not tested.
        folds: the leave-one-out folds over the calibration logs.
        k_sigma: the significance threshold in σ.

    Returns:
        The value, ``used`` False where the nominal stays, with the reason.
    """
    if not value.excited:
        return value
    if nominal is None:
        return replace(value, decision="reported only (the estimators do not use it)")
    unit = "" if value.unit == "-" else f" {value.unit}"
    z = abs(value.value - nominal) / value.sigma if value.sigma > 0 else math.inf
    cal_ss = nom_ss = 0.0
    n = 0
    for f in folds:
        if f.held is None or not f.held.excited or not f.held.sigma > 0:
            continue
        train = f.train.value if f.train is not None and f.train.excited else nominal
        cal_ss += ((train - f.held.value) / f.held.sigma) ** 2
        nom_ss += ((nominal - f.held.value) / f.held.sigma) ** 2
        n += 1
    cv = (f"held-out χ² {cal_ss:.3g} against the nominal's {nom_ss:.3g} ({n} fold"
          f"{'s' if n != 1 else ''})")
    if z <= k_sigma:
        why = f"nominal {nominal:.6g}{unit} kept: within {z:.2g}σ ≤ {k_sigma:g}σ of it"
        return replace(value, used=False, decision=why)
    if n == 0:
        why = (f"nominal {nominal:.6g}{unit} kept: {z:.2g}σ from it, but no held-out log "
               "excites it, so nothing shows that it generalises")
        return replace(value, used=False, decision=why)
    if not cal_ss < nom_ss:
        why = f"nominal {nominal:.6g}{unit} kept: {z:.2g}σ from it, but {cv}"
        return replace(value, used=False, decision=why)
    return replace(value, used=True,
                   decision=f"used: {z:.2g}σ from nominal {nominal:.6g}{unit}; {cv}")


COUPLED = {"sigma0_y": ("cy_f", "cy_r"), "kappa_y": ("cy_f", "cy_r")}
"""Values used only where the values they imply are used: σ0y/κy is the Pipeline's
cornering-stiffness prior per unit load unless ``cy_f`` and ``cy_r`` are used."""


def couple(values: dict[str, Identified]) -> dict[str, Identified]:
    """``values`` with each :data:`COUPLED` value not used where its partners are not."""
    out = dict(values)
    for key, partners in COUPLED.items():
        v = out.get(key)
        if v is None or not v.used or not v.excited:
            continue
        missing = [p for p in partners if p not in out or not out[p].excited or not out[p].used]
        if missing:
            out[key] = replace(v, used=False, decision=(
                f"nominal kept: σ0y/κy is the cornering-stiffness prior, and {', '.join(missing)} "
                f"(its direct identification) is not used; alone: {v.decision}"))
    return out
