"""Longitudinal chassis balance: wheel torques implied by the measured specific force.

For logs without wheel torques (most conventional cars' CAN logs; the gap named
in 001 Sec. VI) the net wheel torques are reconstructed from the chassis
equation and a torque distribution. Pure NumPy, vectorised over samples; arrays
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


def rolling_sign(omega: np.ndarray) -> np.ndarray:
    """s(ω) = clip(ω/ω_0, −1, 1): direction of the rolling-resistance moment, faded near standstill."""
    return np.clip(omega / RR_OMEGA0, -1.0, 1.0)


@njit(cache=True, error_model="numpy")
def torque_less_rolling_resistance(torque: np.ndarray, omega: np.ndarray, fz: np.ndarray,
                                   f_radius: float) -> np.ndarray:
    """T_i − f R F_z,i s(ω_i) (n, 4), N m: the net wheel torque less the rolling-resistance
    moment of 000 eq. (1)'s wheel (``f_radius`` = f·R, m; s as :func:`rolling_sign`)."""
    out = np.empty(torque.shape)
    for k in range(torque.shape[0]):
        for i in range(torque.shape[1]):
            rr = f_radius * fz[k, i]
            out[k, i] = torque[k, i] - rr * min(max(omega[k, i] / RR_OMEGA0, -1.0), 1.0)
    return out


def steered_drag(f_y: np.ndarray, delta_front: np.ndarray, mass: float, lf: float,
                 lr: float) -> np.ndarray:
    """C of eq. (1): Σ_front F_y,i tan δ_i ≈ (m l_r/L) f_y tan δ̄_f, N, shape (n,).

    Args:
        f_y: road-plane lateral specific force at the CG (n,), m/s².
        delta_front: mean front road-wheel angle (n,), rad.
        mass: kg; lf, lr: CG to front and rear axle, m.
    """
    return mass * lr / (lf + lr) * f_y * np.tan(delta_front)


def total_wheel_torque(force_total: np.ndarray, fz: np.ndarray, omega: np.ndarray,
                       omega_dot: np.ndarray, wheel_inertia: float, radius: float,
                       rolling_resistance: float) -> np.ndarray:
    """Net torque of all four wheels together, eq. (2) of the module docstring, N m, shape (n,).

    Args:
        force_total: Σ F_x,i of eq. (1) (n,), N.
        fz: normal load per corner (n, 4), N.
        omega: wheel speed per corner (n, 4), rad/s (for the rolling-resistance sign).
        omega_dot: wheel acceleration per corner (n, 4), rad/s².
        wheel_inertia: one wheel, kg m²; radius: effective rolling radius, m.
        rolling_resistance: coefficient f (moment f R F_z).
    """
    rr = rolling_resistance * np.sum(fz * rolling_sign(omega), axis=1)
    return radius * (force_total + rr) + wheel_inertia * np.sum(omega_dot, axis=1)


def distribute_torque(total: np.ndarray, drive_front: float, brake_front: float) -> np.ndarray:
    """Corner torques (n, 4) from the total (n,): drive split while Σ T > 0, brake balance otherwise.

    Args:
        total: Σ T_i, N m.
        drive_front: front-axle share of drive torque (see :func:`drive_front_share`).
        brake_front: front-axle share of brake torque (``[powertrain] brake_front_share``).
    """
    front = np.where(total > 0.0, drive_front, brake_front)
    half_front = 0.5 * front * total
    half_rear = 0.5 * (1.0 - front) * total
    return np.column_stack((half_front, half_front, half_rear, half_rear))


def drag_speed(f_x: np.ndarray, omega: np.ndarray, radius: float) -> np.ndarray:
    """Speed (n,) in m/s for the drag term: the slowest wheel periphery R ω while f_x ≥ 0, the
    fastest while f_x < 0.

    A driven wheel that spins reads fast and a braked one that locks reads slow, so
    the wheel least likely to slip is the slowest under drive and the fastest under
    braking; the mean would put a spinning wheel's speed, squared, into the drag
    (at 145 rad/s of RWD wheel spin on μ = 0.3 it read 28 m/s for a true 9 m/s).
    """
    v = radius * omega
    return np.where(f_x >= 0.0, v.min(axis=1), v.max(axis=1))


def chassis_wheel_torques(f_x: np.ndarray, f_y: np.ndarray, delta_front: np.ndarray,
                          fz: np.ndarray, omega: np.ndarray, vehicle: Vehicle,
                          omega_dot: np.ndarray | None = None) -> np.ndarray:
    """Equivalent net wheel torques (n, 4) in N m from the chassis equation (module docstring).

    Args:
        f_x, f_y: road-plane specific force at the CG (n,), m/s².
        delta_front: mean front road-wheel angle (n,), rad.
        fz: normal load per corner (n, 4), N.
        omega: wheel speed per corner (n, 4), rad/s.
        vehicle: uses [vehicle] mass, lf, lr, wheel_inertia, wheel_radius and
            drivetrain, [aerodynamics] (drag and rolling resistance) and [powertrain]
            front_drive_share and brake_front_share (their defaults when the file
            has no such tables).
        omega_dot: wheel acceleration per corner (n, 4), rad/s², or None for the
            rolling-without-slip approximation ω̇_i = f_x/R.
    """
    b, a, pt = vehicle.body, vehicle.stated_aerodynamics, vehicle.powertrain
    speed = drag_speed(f_x, omega, b.wheel_radius)
    drag = 0.5 * a.air_density * a.drag_area * speed * np.abs(speed)
    force = b.mass * f_x + drag + steered_drag(f_y, delta_front, b.mass, b.lf, b.lr)
    if omega_dot is None:
        omega_dot = np.repeat((f_x / b.wheel_radius)[:, None], 4, axis=1)
    total = total_wheel_torque(force, fz, omega, omega_dot, b.wheel_inertia, b.wheel_radius,
                               a.rolling_resistance)
    return distribute_torque(total, drive_front_share(b.drivetrain, pt.front_drive_share),
                             pt.brake_front_share)
