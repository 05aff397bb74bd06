"""Planar rigid-body kinematics between the CG, the wheel centres and the tire frames.

Pure functions, vectorised over samples (the rotations are one-pass Numba loops);
arrays with a corner axis have shape (n, 4) in the order fl, fr, rl, rr. Body axes
ISO 8855 (x forward, y left).
Corner i sits at (x_i, y_i) = (l_f, t_f/2), (l_f, −t_f/2), (−l_r, t_r/2), (−l_r, −t_r/2).

* Wheel-centre velocity (001 eq. (33), (42) read backwards): v_x,i = v_x − r y_i,
  v_y,i = v_y + r x_i; the CG from a corner: v_x = v_x,i + r y_i, v_y = v_y,i − r x_i.
* Acceleration transported to a corner (001 text after eq. (21)):
  a_x,i = a_x − ṙ y_i − r² x_i, a_y,i = a_y + ṙ x_i − r² y_i.
* Tire frame, rotated by the steering angle δ_i (000 eq. (28)):
  v_xt = v_x,i cos δ + v_y,i sin δ, v_yt = −v_x,i sin δ + v_y,i cos δ, and back.
* Slip ratio and slip angle as the spec defines them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.io.vehicle import Vehicle


def corner_positions(vehicle: Vehicle) -> tuple[np.ndarray, np.ndarray]:
    """(x_i, y_i) of the four wheel centres relative to the CG, m, each shape (4,)."""
    b = vehicle.body
    xw = np.array([b.lf, b.lf, -b.lr, -b.lr])
    yw = 0.5 * np.array([b.track_f, -b.track_f, b.track_r, -b.track_r])
    return xw, yw


@njit(cache=True, error_model="numpy")
def transport_kernel(a: np.ndarray, b: np.ndarray, c: np.ndarray, w: np.ndarray, s: np.ndarray,
               sign: float) -> tuple[np.ndarray, np.ndarray]:
    """out_x[k, i] = a[k] − sign·c[k] y_i, out_y[k, i] = b[k] + sign·c[k] x_i for (n,) a, b, c
    and (4,) positions (w = x_i, s = y_i); one pass, no temporaries."""
    n = a.shape[0]
    out_x = np.empty((n, 4))
    out_y = np.empty((n, 4))
    for k in range(n):
        for i in range(4):
            out_x[k, i] = a[k] - sign * c[k] * s[i]
            out_y[k, i] = b[k] + sign * c[k] * w[i]
    return out_x, out_y


def _flat(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float).reshape(-1)


def cg_to_corners(vx: np.ndarray, vy: np.ndarray, yaw_rate: np.ndarray, xw: np.ndarray,
                  yw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wheel-centre velocities (n, 4) in the body frame from the CG velocity (n,) and yaw rate."""
    return transport_kernel(_flat(vx), _flat(vy), _flat(yaw_rate), _flat(xw), _flat(yw), 1.0)


def corners_to_cg(vx_i: np.ndarray, vy_i: np.ndarray, yaw_rate: np.ndarray, xw: np.ndarray,
                  yw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each corner's estimate of the CG velocity (n, 4): v_x = v_x,i + r y_i, v_y = v_y,i − r x_i."""
    return (vx_i + yaw_rate[:, None] * yw[None, :], vy_i - yaw_rate[:, None] * xw[None, :])


@njit(cache=True, error_model="numpy")
def euler_rates(p: float, q: float, r: float, roll: float, pitch: float) -> tuple[float, float]:
    """Roll and pitch rates φ̇, θ̇ (rad/s) of the Z-Y-X Euler angles from the body rates
    p, q, r (rad/s) of the gyro at roll φ and pitch θ (rad):
        φ̇ = p + (q sin φ + r cos φ) tan θ,   θ̇ = q cos φ − r sin φ.
    A rolled body turning at r reads r sin φ on its pitch gyro (a 0.33 rad/s turn at 4.4°
    of roll: 0.025 rad/s) that is not a pitch motion."""
    s, c = np.sin(roll), np.cos(roll)
    return p + (q * s + r * c) * np.tan(pitch), q * c - r * s


@njit(cache=True, error_model="numpy")
def yaw_acceleration_kernel(t: np.ndarray, r: np.ndarray, prev: np.ndarray,
                            out: np.ndarray) -> None:
    """Yaw acceleration ṙ_k = (r_k − r_{k−1})/(t_k − t_{k−1}) by backward differences, rad/s²,
    into ``out``; ``prev`` = [t, r] of the sample before ``t[0]`` (NaN t: none, ṙ = 0 there),
    updated to the last sample's, so consecutive chunks give the whole log's differences. A
    NaN difference (a NaN rate) is 0."""
    tp, rp = prev[0], prev[1]
    for k in range(t.shape[0]):
        dt = t[k] - tp
        a = (r[k] - rp) / dt if dt > 0.0 else 0.0
        out[k] = 0.0 if np.isnan(a) else a
        tp, rp = t[k], r[k]
    prev[0], prev[1] = tp, rp


@njit(cache=True, error_model="numpy")
def corner_acc_kernel(ax: np.ndarray, ay: np.ndarray, r: np.ndarray, r_dot: np.ndarray,
                xw: np.ndarray, yw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = ax.shape[0]
    out_x = np.empty((n, 4))
    out_y = np.empty((n, 4))
    for k in range(n):
        r2 = r[k] * r[k]
        for i in range(4):
            out_x[k, i] = ax[k] - r_dot[k] * yw[i] - r2 * xw[i]
            out_y[k, i] = ay[k] + r_dot[k] * xw[i] - r2 * yw[i]
    return out_x, out_y


def corner_accelerations(ax: np.ndarray, ay: np.ndarray, yaw_rate: np.ndarray,
                         yaw_acc: np.ndarray, xw: np.ndarray,
                         yw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Acceleration (n, 4) of each wheel centre in the body frame, m/s², from the CG's (n,)."""
    return corner_acc_kernel(_flat(ax), _flat(ay), _flat(yaw_rate), _flat(yaw_acc), _flat(xw),
                       _flat(yw))


@njit(cache=True, error_model="numpy")
def rotate_kernel(vx: np.ndarray, vy: np.ndarray, delta: np.ndarray, sign: float,
            out_x: np.ndarray, out_y: np.ndarray) -> None:
    """Rotate (v_x, v_y) by −sign·δ elementwise (flat arrays), one pass, no temporaries."""
    for k in range(vx.shape[0]):
        c = np.cos(delta[k])
        s = sign * np.sin(delta[k])
        out_x[k] = vx[k] * c + vy[k] * s
        out_y[k] = -vx[k] * s + vy[k] * c


def _rotated(vx: np.ndarray, vy: np.ndarray, delta: np.ndarray,
             sign: float) -> tuple[np.ndarray, np.ndarray]:
    vx, vy, delta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (vx, vy, delta)))
    out_x = np.empty(vx.shape)
    out_y = np.empty(vx.shape)
    rotate_kernel(np.ascontiguousarray(vx).reshape(-1), np.ascontiguousarray(vy).reshape(-1),
            np.ascontiguousarray(delta).reshape(-1), sign, out_x.reshape(-1),
            out_y.reshape(-1))
    return out_x, out_y


def to_tire_frame(vx: np.ndarray, vy: np.ndarray,
                  delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame vectors (n, 4) rotated into each wheel's frame by its steering angle δ (n, 4):
    v_xt = v_x cos δ + v_y sin δ, v_yt = −v_x sin δ + v_y cos δ (000 eq. (28))."""
    return _rotated(vx, vy, delta, 1.0)


def to_body_frame(vxt: np.ndarray, vyt: np.ndarray,
                  delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`to_tire_frame`."""
    return _rotated(vxt, vyt, delta, -1.0)


@njit(cache=True, error_model="numpy")
def slip_ratio_kernel(omega: np.ndarray, vxt: np.ndarray, radius: float, eps: float,
                out: np.ndarray) -> None:
    for k in range(omega.shape[0]):
        rw = radius * omega[k]
        den = max(abs(rw), abs(vxt[k]))
        out[k] = (rw - vxt[k]) / den if den > eps else 0.0


@njit(cache=True, error_model="numpy")
def slip_angle_kernel(vxt: np.ndarray, vyt: np.ndarray, eps: float, out: np.ndarray) -> None:
    for k in range(vxt.shape[0]):
        out[k] = np.arctan(vyt[k] / vxt[k]) if abs(vxt[k]) > eps else 0.0


def slip_ratio(omega: np.ndarray, vxt: np.ndarray, radius: float, eps: float = 0.1) -> np.ndarray:
    """(R ω − v_xt)/max(|R ω|, |v_xt|) (spec; magnitudes so it stays bounded at standstill and
    when reversing); 0 where both speeds are below ``eps`` m/s."""
    omega, vxt = np.broadcast_arrays(np.asarray(omega, dtype=float), np.asarray(vxt, dtype=float))
    out = np.empty(omega.shape)
    slip_ratio_kernel(_flat(omega), _flat(vxt), float(radius), float(eps), out.reshape(-1))
    return out


def slip_angle(vxt: np.ndarray, vyt: np.ndarray, eps: float = 0.5) -> np.ndarray:
    """atan(v_yt / v_xt) in the tire frame (spec: negative in a steady left turn); 0 below ``eps`` m/s."""
    vxt, vyt = np.broadcast_arrays(np.asarray(vxt, dtype=float), np.asarray(vyt, dtype=float))
    out = np.empty(vxt.shape)
    slip_angle_kernel(_flat(vxt), _flat(vyt), float(eps), out.reshape(-1))
    return out


@njit(cache=True, error_model="numpy")
def middle_wheel_speed(omega: np.ndarray, k: int, radius: float) -> float:
    """Mean R ω of the two middle wheels of sample ``k`` (m/s): a speed reference robust to
    one wheel spinning and one locking (``omega`` (n, 4) rad/s)."""
    a, b, c, d = omega[k, 0], omega[k, 1], omega[k, 2], omega[k, 3]
    hi = max(max(a, b), max(c, d))
    lo = min(min(a, b), min(c, d))
    return 0.5 * radius * (a + b + c + d - hi - lo)


@njit(cache=True, error_model="numpy")
def road_specific_force(ax: np.ndarray, ay: np.ndarray, az: np.ndarray, roll: np.ndarray,
                        pitch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IMU specific force rotated from the body to the road plane: (f_x, f_y, f_z) in m/s².

    Inverse of the body rotation (pitch θ, then roll φ): 001 eq. (14) for x and z;
    for y the spec's roll sign (φ > 0 lifts the left side) gives f_y = a_y cos φ − a_z sin φ.
    """
    cp, sp = np.cos(roll), np.sin(roll)
    ct, st = np.cos(pitch), np.sin(pitch)
    f_y = cp * ay - sp * az
    tmp_z = sp * ay + cp * az  # body z-axis component after removing roll
    f_x = ct * ax + st * tmp_z
    f_z = -st * ax + ct * tmp_z
    return f_x, f_y, f_z


@njit(cache=True, error_model="numpy")
def level_road_az(ax: np.ndarray, ay: np.ndarray, roll: np.ndarray,
                  pitch: np.ndarray) -> np.ndarray:
    """Body-frame a_z (m/s²) for a log without ``az``: the value whose road-normal component is g.

    Solves f_z = g in :func:`road_specific_force` for a_z given a_x, a_y and the body
    angles: a_z = ((g + a_x sin θ)/cos θ − a_y sin φ)/cos φ. It assumes a level road
    without heave; on a grade or bank γ the true f_z is g cos γ (0.1 % less at 5 %),
    and road undulations and heave, which a measured a_z carries into the normal
    loads, are lost. Better than a_z = g, which would put g(1 − cos θ cos φ) of
    error into f_x and f_z at the body angles of hard braking or cornering.
    """
    cp, sp = np.cos(roll), np.sin(roll)
    ct, st = np.cos(pitch), np.sin(pitch)
    return ((G + st * ax) / ct - sp * ay) / cp
