"""Longitudinal chassis balance: wheel torques implied by the measured specific force.

For logs without wheel torques (most conventional cars' CAN logs; the gap named
in 001 Sec. VI) the net wheel torques are reconstructed from the chassis
equation and a torque distribution, one compiled pass over the samples; arrays
with a corner axis have shape (n, 4) in the order fl, fr, rl, rr. Units SI.

**Chassis equation.** The body's longitudinal balance on a road of grade γ
(the plant of :mod:`vestim.sim.plant`, 000 eq. (1)'s chassis counterpart) is
m(v̇_x − r v_y) = Σ (F_x,i cos δ_i − F_y,i sin δ_i) − D − m g sin γ, with F_x,i,
F_y,i the road forces on the tires in each tire's frame (rolling resistance
included: a free-rolling tire reads −f F_z) and D the aerodynamic drag. The
accelerometer measures *specific force*, f_x = (v̇_x − r v_y) + g sin γ once
rotated into the road plane (:func:`vestim.models.kinematics.road_specific_force`),
so the grade term cancels and

    Σ F_x,i = m f_x + D + C,    D = ½ ρ C_dA v_x |v_x|,    C = Σ_front F_y,i tan δ_i.   (1)

No grade estimate is needed: gravity along the slope acts on the whole body and
on the accelerometer's proof mass alike, so only the tires' share of the balance
appears in f_x. C is the backward component of the steered tires' lateral force,
which the longitudinal tire forces must overcome (472 N at 7 m/s² and 0.06 rad of
road-wheel angle on the SUV); with the front axle's lateral force from the
quasi-steady single-track balance, F_yf = m l_r f_y / L, it is C ≈ (m l_r/L) f_y tan δ̄_f.
(The yaw-acceleration part I_z ṙ/L of F_yf is left out: differentiating the gyro at
200 Hz would put more noise in than it removes; the cos δ_i factors are 1 to 0.2 %
at 0.06 rad.)

**Net wheel torque.** The wheel dynamics (000 eq. (1), plus the rolling-resistance
moment) I_w ω̇_i = T_i − R F_x,i − f R F_z,i s(ω_i) summed over the wheels give
the total net torque

    Σ T_i = R (Σ F_x,i + f Σ F_z,i s(ω_i)) + I_w Σ ω̇_i,                      (2)

with s(ω) = clip(ω/ω_0, −1, 1) the rolling-resistance sign (ω_0 = 3 rad/s, as in
the force estimator). The wheel accelerations ω̇_i are the caller's estimate (the
force estimator passes its own filtered ω̇, so that a wheel spinning up is given
the torque that spins it up); without one, wheels rolling without gross slip give
Σ ω̇_i ≈ 4 v̇_x/R ≈ 4 f_x/R, the familiar equivalent mass m + 4 I_w/R² (off by
4 I_w g sin γ/R² on a grade γ, about 30 N in total for the SUV on 5 %, and wrong
whenever a wheel spins up or locks).

**Distribution.** The total is split over the axles by the torque split of the
powertrain while the net torque drives (Σ T > 0): the front share is
``[powertrain] front_drive_share`` for AWD, 1 for FWD, 0 for RWD; and by the
brake balance ``[powertrain] brake_front_share`` while it brakes (Σ T < 0). The
distribution is continuous in Σ T (both branches give 0 at Σ T = 0). Left and
right get equal torque: an open differential, which is what a car whose wheel
torques are not on its bus usually has. What it cannot know: per-wheel traction-
control or ABS torque cuts, torque vectoring, individually controlled in-wheel
motors (a wheel spinning on the icy side of a split-μ launch, whose motor torque
is cut, is given half of its axle's torque), regenerative braking that moves
the brake balance. The axle totals stay right in all these cases.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vestim.io.vehicle import DRIVETRAINS, Vehicle

RR_OMEGA0 = 3.0
"""rad/s; the rolling-resistance moment fades in linearly over |ω| < ω_0 (1 m/s at R = 0.33 m)."""


def drive_front_share(drivetrain: str, front_drive_share: float) -> float:
    """Front-axle share of the drive torque: AWD the powertrain's split, FWD 1, RWD 0."""
    if drivetrain not in DRIVETRAINS:
        raise ValueError(f"drivetrain {drivetrain!r}: use one of {', '.join(DRIVETRAINS)}")
    return {"awd": front_drive_share, "fwd": 1.0, "rwd": 0.0}[drivetrain]


@njit(cache=True, error_model="numpy")
def torque_less_rolling_resistance(torque: np.ndarray, omega: np.ndarray, fz: np.ndarray,
                                   f_radius: float) -> np.ndarray:
    """T_i − f R F_z,i s(ω_i) (n, 4), N m: the net wheel torque less the rolling-resistance
    moment of 000 eq. (1)'s wheel (``f_radius`` = f·R, m; s(ω) = clip(ω/ω_0, −1, 1) as in
    the module docstring)."""
    out = np.empty(torque.shape)
    for k in range(torque.shape[0]):
        for i in range(torque.shape[1]):
            rr = f_radius * fz[k, i]
            out[k, i] = torque[k, i] - rr * min(max(omega[k, i] / RR_OMEGA0, -1.0), 1.0)
    return out


class ChassisKernelParams(NamedTuple):
    """:func:`chassis_torque_kernel`'s parameters (SI), from :func:`chassis_params`."""

    mass: float  # kg
    steer_share: float  # m l_r/L, kg: the front axle's share of m f_y (C of eq. (1))
    drag_coef: float  # ½ ρ C_dA, kg/m
    wheel_inertia: float  # one wheel, kg m²
    radius: float  # m
    rolling_resistance: float  # f (moment f R F_z)
    drive_front: float  # front share of drive torque (see drive_front_share)
    brake_front: float  # front share of brake torque


def chassis_params(vehicle: Vehicle) -> ChassisKernelParams:
    """The chassis equation's parameters: [vehicle] mass, lf, lr, wheel_inertia, wheel_radius
    and drivetrain, [aerodynamics] (drag and rolling resistance) and [powertrain]
    front_drive_share and brake_front_share (their defaults when the file has no such
    tables)."""
    b, a, pt = vehicle.body, vehicle.stated_aerodynamics, vehicle.powertrain
    return ChassisKernelParams(
        float(b.mass), float(b.mass * b.lr / (b.lf + b.lr)),
        float(0.5 * a.air_density * a.drag_area), float(b.wheel_inertia),
        float(b.wheel_radius), float(a.rolling_resistance),
        float(drive_front_share(b.drivetrain, pt.front_drive_share)),
        float(pt.brake_front_share))


@njit(cache=True, error_model="numpy")
def distribute_torque(total: np.ndarray, drive_front: float, brake_front: float) -> np.ndarray:
    """Corner torques (n, 4) from the total (n,): drive split while Σ T > 0, brake balance otherwise.

    Args:
        total: Σ T_i, N m.
        drive_front: front-axle share of drive torque (see :func:`drive_front_share`).
        brake_front: front-axle share of brake torque (``[powertrain] brake_front_share``).
    """
    out = np.empty((total.shape[0], 4))
    for k in range(total.shape[0]):
        front = drive_front if total[k] > 0.0 else brake_front
        out[k, 0] = out[k, 1] = 0.5 * front * total[k]
        out[k, 2] = out[k, 3] = 0.5 * (1.0 - front) * total[k]
    return out


@njit(cache=True, error_model="numpy")
def chassis_torque_kernel(f_x: np.ndarray, f_y: np.ndarray, delta_front: np.ndarray,
                          fz: np.ndarray, omega: np.ndarray, omega_dot: np.ndarray,
                          p: ChassisKernelParams) -> np.ndarray:
    """Equivalent net wheel torques (n, 4), N m, by eq. (1), (2) and the distribution of the
    module docstring: f_x, f_y road-plane specific force (n,), m/s²; delta_front the mean
    front road-wheel angle (n,), rad; fz (n, 4) N; omega (n, 4) rad/s; omega_dot (n, 4)
    rad/s².

    The drag's speed is the slowest wheel periphery R ω while f_x ≥ 0, the fastest while
    f_x < 0: a driven wheel that spins reads fast and a braked one that locks reads slow, so
    the wheel least likely to slip is the slowest under drive and the fastest under braking
    (the mean put a spinning wheel's speed, squared, into the drag: at 145 rad/s of RWD wheel
    spin on μ = 0.3 it read 28 m/s for a true 9 m/s). C of eq. (1) is (m l_r/L) f_y tan δ̄_f."""
    n = f_x.shape[0]
    total = np.empty(n)
    for k in range(n):
        lo = hi = p.radius * omega[k, 0]
        rr = 0.0
        spin = 0.0
        for i in range(4):
            v = p.radius * omega[k, i]
            lo, hi = min(lo, v), max(hi, v)
            rr += fz[k, i] * min(max(omega[k, i] / RR_OMEGA0, -1.0), 1.0)
            spin += omega_dot[k, i]
        speed = lo if f_x[k] >= 0.0 else hi
        force = (p.mass * f_x[k] + p.drag_coef * speed * abs(speed)
                 + p.steer_share * f_y[k] * np.tan(delta_front[k]))
        total[k] = p.radius * (force + p.rolling_resistance * rr) + p.wheel_inertia * spin
    return distribute_torque(total, p.drive_front, p.brake_front)


def chassis_wheel_torques(f_x: np.ndarray, f_y: np.ndarray, delta_front: np.ndarray,
                          fz: np.ndarray, omega: np.ndarray, vehicle: Vehicle,
                          omega_dot: np.ndarray | None = None) -> np.ndarray:
    """Equivalent net wheel torques (n, 4) in N m from the chassis equation (module docstring).

    Args:
        f_x, f_y: road-plane specific force at the CG (n,), m/s².
        delta_front: mean front road-wheel angle (n,), rad.
        fz: normal load per corner (n, 4), N.
        omega: wheel speed per corner (n, 4), rad/s.
        vehicle: see :func:`chassis_params`.
        omega_dot: wheel acceleration per corner (n, 4), rad/s², or None for the
            rolling-without-slip approximation ω̇_i = f_x/R.
    """
    p = chassis_params(vehicle)
    f_x = np.ascontiguousarray(f_x, dtype=float)
    if omega_dot is None:
        omega_dot = np.repeat((f_x / p.radius)[:, None], 4, axis=1)
    return chassis_torque_kernel(f_x, np.ascontiguousarray(f_y, dtype=float),
                                 np.ascontiguousarray(delta_front, dtype=float),
                                 np.ascontiguousarray(fz, dtype=float),
                                 np.ascontiguousarray(omega, dtype=float),
                                 np.ascontiguousarray(omega_dot, dtype=float), p)
