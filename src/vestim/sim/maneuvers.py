"""Named maneuvers: driver inputs and road, as a test driver would specify them.

A :class:`Maneuver` holds the steering-wheel angle, the pedals (or a target
speed for the driver's speed-hold loop) as functions of time, the road, the
initial speed and the vehicle options (drivetrain, tire plant, TC, ABS). Each
named maneuver is built by a factory that takes the common options ``mu``,
``v0``, ``drivetrain``, ``tire``, ``tc``, ``abs_`` (``None`` keeps the
maneuver's own default); :func:`get_maneuver` looks them up by name.

Where a paper states the inputs they are reproduced and cited; otherwise the
choice is stated in the factory's docstring. Steering inputs are steering-wheel
angles sized for the SUV of 000/001 Table I (wheelbase 2.85 m, ratio 16.7), as a
driver's would be: on another vehicle the same input gives another radius.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from vestim.errors import ManeuverError
from vestim.sim.road import Road

Signal = Callable[[np.ndarray], np.ndarray]
TIRES: tuple[str, ...] = ("magic", "lugre")


def kph(v: float) -> float:
    """km/h → m/s."""
    return v / 3.6


def _zero(t: np.ndarray) -> np.ndarray:
    return np.zeros_like(t)


def _nan(t: np.ndarray) -> np.ndarray:
    return np.full_like(t, np.nan)


def piecewise(times: list[float], values: list[float]) -> Signal:
    """Piecewise-linear signal through (times, values), held outside."""
    tk = np.asarray(times, dtype=float)
    vk = np.asarray(values, dtype=float)
    return lambda t: np.interp(t, tk, vk)


def square_wave(period: float, low: float, high: float, start: float = 0.0) -> Signal:
    """Square wave starting high at ``start`` (held at ``low`` before), 50 % duty."""
    def sig(t: np.ndarray) -> np.ndarray:
        phase = np.mod(t - start, period) < 0.5 * period
        return np.where(t < start, low, np.where(phase, high, low))
    return sig


def sine_pulses(pulses: list[tuple[float, float, float]]) -> Signal:
    """Sum of full-period sine pulses (start s, period s, amplitude)."""
    def sig(t: np.ndarray) -> np.ndarray:
        out = np.zeros_like(t)
        for t0, period, amp in pulses:
            inside = (t >= t0) & (t <= t0 + period)
            out = out + np.where(inside, amp * np.sin(2 * np.pi * (t - t0) / period), 0.0)
        return out
    return sig


@dataclass(frozen=True)
class Maneuver:
    """A complete test: inputs, road, initial speed and vehicle options.

    Attributes:
        name: library name.
        description: one line, with the paper reference where there is one.
        duration: s.
        v0: initial speed, m/s (straight, free-rolling wheels).
        steering_wheel_angle: rad over time (> 0 steers left).
        throttle, brake: pedal positions in [0, 1] over time.
        speed: target speed in m/s over time for the driver's speed hold (NaN: open-loop pedals).
        road: friction, stiffness factor, grade and bank.
        drivetrain: "awd" | "fwd" | "rwd", or None for the vehicle file's.
        tire: "magic" | "lugre".
        tc, abs_: traction control and ABS on or off.
    """

    name: str
    description: str
    duration: float
    v0: float
    steering_wheel_angle: Signal
    throttle: Signal
    brake: Signal
    speed: Signal
    road: Road
    drivetrain: str | None = None
    tire: str = "magic"
    tc: bool = False
    abs_: bool = False


# ----------------------------------------------------------------- factories
def accel_brake(mu: float = 0.3, v0: float = kph(30)) -> Maneuver:
    """Successive accelerator and brake requests on μ = 0.3 from 30 km/h (000 Fig. 6a).

    000 gives the road and initial speed, not the pedal profile; we use
    alternating pulses with slip of both signs, sized for μ = 0.3 on the SUV
    (0.3·m·g·R ≈ 2200 N m of wheel torque): throttle 30 % (1–3 s), brake 10 %
    (3.5–5.5 s), throttle 50 % (6–8 s), brake 18 % (8.5–10.5 s), throttle 20 % (11–13 s).
    """
    thr = piecewise([0, 1, 1.1, 3, 3.1, 6, 6.1, 8, 8.1, 11, 11.1, 13, 13.1],
                    [0, 0, 0.3, 0.3, 0, 0, 0.5, 0.5, 0, 0, 0.2, 0.2, 0])
    brk = piecewise([0, 3.5, 3.6, 5.5, 5.6, 8.5, 8.6, 10.5, 10.6],
                    [0, 0, 0.10, 0.10, 0, 0, 0.18, 0.18, 0])
    return Maneuver("accel_brake", "successive accelerate/brake on low mu (000 Fig. 6a)",
                    15.0, v0, _zero, thr, brk, _nan, Road.uniform(mu))


def _ait_000(name: str, road: Road, v0: float, what: str) -> Maneuver:
    thr = piecewise([0, 2, 2.05, 4, 4.05, 6, 6.05, 11, 15], [0, 0, 1, 1, 0, 0, 1, 1, 0])
    swa = piecewise([0, 2, 2.2, 12, 12.2], [0, 0, 1.0, 1.0, 0])
    return Maneuver(name, what, 16.0, v0, swa, thr, _zero, _nan, road)


def ait_dry(mu: float = 1.0, v0: float = kph(30)) -> Maneuver:
    """Acceleration-in-turn on dry road, inputs of 000 Sec. IV-A.

    Accelerator 100 % at 2–4 s, released 4–6 s, 100 % again 6–11 s, linearly to
    zero at 15 s; steering-wheel angle 1 rad from 2 to 12 s (0.2 s ramps).
    The initial speed is not given; 30 km/h.
    """
    return _ait_000("ait_dry", Road.uniform(mu), v0, "acceleration-in-turn, dry (000 Sec. IV-A)")


def ait_slippery(mu: float = 0.3, v0: float = kph(30)) -> Maneuver:
    """Acceleration-in-turn on μ = 0.3 with the inputs of :func:`ait_dry` (000 Sec. IV-A).

    Traction/stability control is on by default: with 100 % throttle and a fixed
    steering wheel on μ = 0.3 the uncontrolled car spins out (β > 2 rad).
    """
    m = _ait_000("ait_slippery", Road.uniform(mu), v0,
                 "acceleration-in-turn, mu 0.3 (000 Sec. IV-A)")
    return replace(m, tc=True)


def _ait_004(name: str, mu: float, v0: float) -> Maneuver:
    # Traction/stability control on: the open-loop steering at a speed rising to
    # ~25 m/s asks for more than μg, and without it the car spins.
    swa_max = 0.05 * 16.7  # road-wheel angle 0.05 rad with the SUV's ratio
    thr = piecewise([0, 5, 5.05, 10, 10.05], [0, 0, 1, 1, 0])
    swa = piecewise([0, 1, 2], [0, 0, swa_max])
    m = Maneuver(name, f"acceleration-in-turn, mu {mu} (004 Sec. IV, Fig. 8)", 14.0, v0,
                 swa, thr, _zero, _nan, Road.uniform(mu))
    return replace(m, tc=True)


def ait_004_dry(mu: float = 1.0, v0: float = kph(30)) -> Maneuver:
    """Acceleration-in-turn of 004 Sec. IV (Fig. 8): road-wheel angle up to 0.05 rad, gas 100 % at 5–10 s.

    The steering is ramped to 0.05 rad (×16.7 at the steering wheel) over 1–2 s;
    the initial speed is not given, 30 km/h.
    """
    return _ait_004("ait_004_dry", mu, v0)


def ait_004_slippery(mu: float = 0.3, v0: float = kph(30)) -> Maneuver:
    """:func:`ait_004_dry` on μ = 0.3 (004 Fig. 8)."""
    return _ait_004("ait_004_slippery", mu, v0)


def step_steer(mu: float = 1.0, v0: float = kph(60)) -> Maneuver:
    """Step steer at 60 km/h, steering-wheel angle 2 rad at t = 2 s on dry road (000 Sec. IV-B).

    The step rises in 0.15 s (a steering robot's rate); the driver holds 60 km/h.
    """
    swa = piecewise([0, 2, 2.15], [0, 0, 2.0])
    return Maneuver("step_steer", "step steer 2 rad at 60 km/h (000 Sec. IV-B)", 8.0, v0, swa,
                    _zero, _zero, lambda t: np.full_like(t, v0), Road.uniform(mu))


def bit_slippery(mu: float = 0.25, v0: float = 15.0) -> Maneuver:
    """Brake-in-turn on μ = 0.25 (004 Fig. 9): road-wheel angle 0.06 rad from 2 s, brake to 100 % at 5 s.

    004 Fig. 9 starts near 15 m/s. The brake pedal ramps to 100 % over 5–5.5 s;
    ABS is on by default (a 100 % brake on μ = 0.25 otherwise locks every wheel).
    """
    swa = piecewise([0, 2, 2.2], [0, 0, 0.06 * 16.7])
    brk = piecewise([0, 5, 5.5], [0, 0, 1.0])
    m = Maneuver("bit_slippery", "brake-in-turn on mu 0.25 (004 Fig. 9)", 12.0, v0, swa, _zero,
                 brk, _nan, Road.uniform(mu))
    return replace(m, abs_=True)


def launch_ice(mu: float = 0.1, v0: float = 0.0) -> Maneuver:
    """Full-throttle launch from standstill on ice (μ = 0.1), straight; TC off by default."""
    thr = piecewise([0, 1, 1.1], [0, 0, 1.0])
    return Maneuver("launch_ice", "full-throttle launch on ice", 10.0, v0, _zero, thr, _zero, _nan,
                    Road.uniform(mu))


def launch_split_mu(mu: float = 0.2, v0: float = 0.0) -> Maneuver:
    """Full-throttle launch on split μ: left wheels dry (μ = 1.0), right wheels on ice.

    001 Sec. VI-B: "the right wheels are on an icy road with μ ≈ 0.2, the left
    wheels are on a dry road"; ``mu`` sets the icy side. Steering held straight.
    """
    thr = piecewise([0, 1, 1.1], [0, 0, 1.0])
    return Maneuver("launch_split_mu", "full-throttle launch, left dry / right ice (001 Sec. VI)",
                    8.0, v0, _zero, thr, _zero, _nan, Road.split(1.0, mu))


def split_mu_brake(mu: float = 0.2, v0: float = kph(80)) -> Maneuver:
    """Straight full braking (80 %) on split μ, left dry, right icy; steering held at zero, no ABS.

    Without a driver's counter-steer the car yaws toward the high-μ (left) side;
    2.5 s keeps the run to the first, physically clean part of the spin.
    """
    brk = piecewise([0, 1, 1.2], [0, 0, 0.8])
    return Maneuver("split_mu_brake", "straight braking on split mu, left dry / right ice", 2.5,
                    v0, _zero, _zero, brk, _nan, Road.split(1.0, mu))


def dlc_snow(mu: float = 0.3, v0: float = kph(50)) -> Maneuver:
    """Double lane change on snow (μ = 0.3) at 50 km/h, as in 000 Fig. 8 and 004 Fig. 15.

    Open-loop steering: a full sine of ±1.2 rad over 2.5 s at 1 s, its mirror at
    4.5 s (ISO 3888-1-like path); the driver holds the speed.
    """
    swa = sine_pulses([(1.0, 2.5, 1.2), (4.5, 2.5, -1.2)])
    return Maneuver("dlc_snow", "double lane change on snow (000 Fig. 8)", 10.0, v0, swa, _zero,
                    _zero, lambda t: np.full_like(t, v0), Road.uniform(mu))


def lc_wet(mu: float = 0.5, v0: float = kph(70)) -> Maneuver:
    """Lane change on wet (μ = 0.5) at 70 km/h (000 Fig. 7, 001 Sec. VI): one sine of 0.9 rad over 3 s."""
    swa = sine_pulses([(1.5, 3.0, 0.9)])
    return Maneuver("lc_wet", "lane change on wet (000 Fig. 7)", 8.0, v0, swa, _zero, _zero,
                    lambda t: np.full_like(t, v0), Road.uniform(mu))


def oval(mu: float = 1.0, v0: float = kph(50)) -> Maneuver:
    """Oval at 50 km/h on dry: straights of 3 s and two left semicircles of 40 m radius.

    Road-wheel angle L/R = 2.85/40 rad (×16.7 at the wheel) held for πR/v ≈ 9 s each.
    """
    swa_turn = 2.85 / 40.0 * 16.7
    half = np.pi * 40.0 / v0
    t1, t2 = 3.0, 3.0 + half
    t3, t4 = t2 + 3.0, t2 + 3.0 + half
    swa = piecewise([0, t1, t1 + 0.5, t2, t2 + 0.5, t3, t3 + 0.5, t4, t4 + 0.5],
                    [0, 0, swa_turn, swa_turn, 0, 0, swa_turn, swa_turn, 0])
    return Maneuver("oval", "oval course at 50 km/h, dry", t4 + 2.0, v0, swa, _zero, _zero,
                    lambda t: np.full_like(t, v0), Road.uniform(mu))


def full_turn_dry_wet(mu: float = 0.5, v0: float = kph(40)) -> Maneuver:
    """A full 360° left turn of 30 m radius at 40 km/h; dry, then wet (``mu``) from 120 m on."""
    swa_turn = 2.85 / 30.0 * 16.7
    t_turn = 2 * np.pi * 30.0 / v0
    swa = piecewise([0, 2, 2.5, 2 + t_turn, 2.5 + t_turn], [0, 0, swa_turn, swa_turn, 0])
    road = Road.transition(1.0, mu, 120.0, by_distance=True)
    return Maneuver("full_turn_dry_wet", "full turn, dry to wet by distance", 4.0 + t_turn, v0,
                    swa, _zero, _zero, lambda t: np.full_like(t, v0), road)


def ait_wet_dry(mu: float = 1.0, v0: float = kph(30)) -> Maneuver:
    """Acceleration-in-turn (inputs of :func:`ait_dry`) from wet (μ = 0.5) onto ``mu`` at t = 7 s."""
    return _ait_000("ait_wet_dry", Road.transition(0.5, mu, 7.0), v0,
                    "acceleration-in-turn, wet to dry at 7 s")


def stiffness_study(mu: float = 1.0, v0: float = 22.0) -> Maneuver:
    """The simulation study of 002 Sec. VI-A: square-wave steering and torque, stiffness drop at 30 s.

    Steering square wave of period 4 s (road-wheel ±0.015 rad) and wheel torque
    square wave of period 5 s (throttle 22 % / brake 5 %, alternating, about
    speed-neutral against drag at 22 m/s), chosen,
    as in 002, so that slip ratios stay below 5 % and slip angles small; x0 =
    [22, 0, 0]; at 30 s the road changes so that tire stiffness falls by 50 %.
    Front-wheel drive (002 estimates the front longitudinal stiffness). 60 s.
    """
    swa = square_wave(4.0, -0.015 * 16.7, 0.015 * 16.7, start=1.0)
    thr = square_wave(5.0, 0.0, 0.22, start=1.0)
    brk = square_wave(5.0, 0.05, 0.0, start=1.0)
    road = Road.transition(mu, mu, 30.0, stiffness_from=1.0, stiffness_to=0.5)
    m = Maneuver("stiffness_study", "002 Sec. VI-A square-wave study, 50 % stiffness drop at 30 s",
                 60.0, v0, swa, thr, lambda t: np.where(t < 1.0, 0.0, brk(t)), _nan, road)
    return replace(m, drivetrain="fwd")


def coast(mu: float = 1.0, v0: float = 25.0) -> Maneuver:
    """Straight coast-down with no pedal input (drag and rolling resistance only)."""
    return Maneuver("coast", "coast-down, no inputs", 10.0, v0, _zero, _zero, _zero, _nan,
                    Road.uniform(mu))


_FACTORIES: dict[str, Callable[..., Maneuver]] = {
    f.__name__: f
    for f in (accel_brake, ait_dry, ait_slippery, ait_004_dry, ait_004_slippery, step_steer,
              bit_slippery, launch_ice, launch_split_mu, split_mu_brake, dlc_snow, lc_wet, oval,
              full_turn_dry_wet, ait_wet_dry, stiffness_study, coast)
}

DEFAULT_SET: tuple[str, ...] = ("accel_brake", "ait_dry", "step_steer", "launch_split_mu",
                                "dlc_snow")
"""Maneuvers of ``make demo``: one per kind of excitation."""


def maneuver_names() -> list[str]:
    """All library names, in library order."""
    return list(_FACTORIES)


def describe(name: str) -> str:
    """One-line description of a named maneuver (with its defaults)."""
    return get_maneuver(name).description


def get_maneuver(name: str, *, mu: float | None = None, v0: float | None = None,
                 drivetrain: str | None = None, tire: str | None = None,
                 tc: bool | None = None, abs_: bool | None = None) -> Maneuver:
    """Build a named maneuver; ``None`` keeps each option at the maneuver's default.

    Raises:
        ManeuverError: unknown name or invalid option (the message lists the valid ones).
    """
    if name not in _FACTORIES:
        raise ManeuverError(f"unknown maneuver {name!r}; choose one of: "
                            f"{', '.join(_FACTORIES)}")
    kwargs: dict[str, Any] = {}
    if mu is not None:
        if not (math.isfinite(mu) and 0 < mu <= 2):
            raise ManeuverError(f"road friction mu = {mu} must be in (0, 2]")
        kwargs["mu"] = mu
    if v0 is not None:
        if not (math.isfinite(v0) and 0 <= v0 <= 100):
            raise ManeuverError(f"initial speed v0 = {v0} m/s must be in [0, 100]")
        kwargs["v0"] = v0
    try:
        m = _FACTORIES[name](**kwargs)
    except ValueError as exc:
        raise ManeuverError(f"maneuver {name!r}: {exc}") from exc
    changes: dict[str, Any] = {}
    if drivetrain is not None:
        if drivetrain not in ("awd", "fwd", "rwd"):
            raise ManeuverError(f"drivetrain {drivetrain!r}: use awd, fwd or rwd")
        changes["drivetrain"] = drivetrain
    if tire is not None:
        if tire not in TIRES:
            raise ManeuverError(f"tire {tire!r}: use one of {', '.join(TIRES)}")
        changes["tire"] = tire
    if tc is not None:
        changes["tc"] = tc
    if abs_ is not None:
        changes["abs_"] = abs_
    return replace(m, **changes)
