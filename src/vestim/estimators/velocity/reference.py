"""Reference-speed Kalman filter: what an ABS/ESC team ships without a tire model.

State x = [v_x, v_y, b_x]: CG velocity in the body frame (m/s) and the bias of
the longitudinal kinematic acceleration (m/s²; accelerometer bias plus the road
grade's g·sin γ, which the IMU cannot tell apart). Process (000 eq. (15)):
    v̇_x = f_x − b_x + r v_y,    v̇_y = f_y − r v_x,    ḃ_x = w_b,
with f the IMU specific force rotated to the road plane by the body angles.
(On a bank the lateral equation sees g·sin β as acceleration; v_y is kept
bounded by the pseudo-measurement below.)

Measurements, sequential scalar updates per sample:
* each wheel's speed mapped to the CG, v_i = R ω_i cos δ_i − v_yt,i sin δ_i + r y_i
  (v_yt,i from the current v_y), with a variance that grows with the evidence of
  slip of that wheel:
    - its use of friction |μ_x,i| (drive or brake force per load, from the force stage),
    - ω̇ inconsistent with the acceleration, |R ω̇_i − a_x| over a 0.1 s window,
    - innovations of the sign slip produces (positive while driving, negative
      while braking) are inflated quadratically,
  and innovation gating (rejected beyond ``gate`` standard deviations);
* optional extra CG-speed measurements (n, m) with their variances — the
  pipeline's fusion feeds the corner-based estimates here;
* the rear-axle slip angle from the estimated rear lateral force and the
  small-slip cornering stiffness of the [tire] table (C_yr = Σ F_z,r σ0y/κy):
  v_y ≈ r l_r − v_x F_yr / C_yr, a weak pseudo-measurement whose variance grows
  with |a_y| (the linear-tire assumption fails near the limit).

A wheel whose measurement is rejected or inflated leaves the filter to the
acceleration integral, whose drift the bias state limits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

VX, VY, BX = 0, 1, 2


@dataclass(frozen=True)
class ReferenceParams:
    """Tuning of the reference filter (one set for every maneuver).

    Attributes:
        q_vx, q_vy: process intensities of v_x, v_y, (m/s)²/s (IMU noise and model error).
        q_bias: random-walk intensity of b_x, (m/s²)²/s (grade changes, bias drift).
        r_wheel: wheel-speed variance at no slip, (m/s)² (sensor noise, radius error).
        k_mu: slip-evidence gain: σ grows by k_mu·|μ_x|·|v| (m/s per unit μ_x).
        k_acc: slip-evidence gain on |R ω̇ − a_x|, s (m/s per m/s²).
        slip_sign: innovation (m/s) at which a slip-signed innovation doubles σ.
        gate: innovation gate in standard deviations.
        r_vy: variance of the v_y ≈ r l_r pseudo-measurement at a_y = 0, (m/s)².
        k_vy: growth of its σ with |a_y|, s.
        bias_max: bound on |b_x|, m/s² (sensor bias plus a grade of about 5 %).
        sigma_corner, sigma_corner_slip: one-sigma (m/s) given by the fused pipeline to a
            corner observer's CG speed outside and inside its high-slip mode.
        window: samples of the ω̇ difference.
    """

    q_vx: float = 0.02
    q_vy: float = 0.05
    q_bias: float = 2.0e-4
    r_wheel: float = 0.05
    k_mu: float = 1.0
    k_acc: float = 0.3
    slip_sign: float = 0.3
    gate: float = 5.0
    r_vy: float = 0.01
    k_vy: float = 0.3
    bias_max: float = 0.5
    window: int = 20
    sigma_corner: float = 5.0
    sigma_corner_slip: float = 0.5


@njit(**_JIT)
def _scalar_update(x: np.ndarray, P: np.ndarray, h: np.ndarray, z: float, r: float,
                   gate: float, ph: np.ndarray) -> float:
    """Kalman update with a scalar measurement z = h·x + v, var(v) = r; returns the innovation.

    P ← P − (P h)(P h)ᵀ/s, symmetrised (for the optimal gain this equals the Joseph
    form); ``ph`` is scratch of length n. Measurements beyond ``gate`` innovation
    standard deviations are rejected (NaN returned, state untouched).
    """
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * h[j]
        ph[i] = acc
    s = r
    zhat = 0.0
    for i in range(n):
        s += h[i] * ph[i]
        zhat += h[i] * x[i]
    innov = z - zhat
    if innov * innov > gate * gate * s:
        return np.nan
    for i in range(n):
        x[i] += ph[i] / s * innov
    for i in range(n):
        for j in range(i, n):
            v = P[i, j] - ph[i] * ph[j] / s
            P[i, j] = v
            P[j, i] = v
    return innov


@njit(**_JIT)
def reference_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                     rear_slip: np.ndarray,
                     f_x: np.ndarray, f_y: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                     extra_v: np.ndarray, extra_var: np.ndarray, radius: float, lr: float,
                     xw: np.ndarray, yw: np.ndarray, prm: np.ndarray, x: np.ndarray, P: np.ndarray,
                     hist: np.ndarray, state: np.ndarray, out_v: np.ndarray,
                     out_sig: np.ndarray, out_bias: np.ndarray,
                     out_trust: np.ndarray) -> None:
    """Advance the reference filter over a chunk, in place on x (3,), P (3, 3), hist, state.

    ``prm`` = [q_vx, q_vy, q_bias, r_wheel, k_mu, k_acc, slip_sign, gate, r_vy, k_vy, bias_max].
    ``hist`` (m, 5): last m samples of (t, ω_fl…ω_rr) for ω̇; ``state`` = [t_prev, started,
    f_x, f_y, r of the previous sample, samples with every wheel rejected]. ``extra_v``/
    ``extra_var`` (n, m2): extra CG-speed
    measurements and variances, NaN where absent. Outputs: out_v (n, 2) [v_x, v_y],
    out_sig (n, 2), out_bias (n,), out_trust (n, 4) the standard deviation used per
    wheel (inf where rejected).
    """
    q_vx, q_vy, q_b, r_w, k_mu, k_acc, s_sign, gate, r_vy, k_vy, bias_max = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9], prm[10])
    m = hist.shape[0]
    h = np.zeros(3)
    ph = np.empty(3)
    F = np.empty((3, 3))
    FP = np.empty((3, 3))
    wheel_v = np.empty(4)
    for k in range(t.shape[0]):
        if state[1] == 0.0:
            v0 = 0.0
            for i in range(4):
                v0 += 0.25 * radius * omega[k, i]
            x[VX] = v0
            x[VY] = 0.0
            x[BX] = 0.0
            P[:, :] = 0.0
            P[VX, VX] = 1.0
            P[VY, VY] = 0.25
            P[BX, BX] = 0.25
            state[1] = 1.0
            for j in range(m):
                hist[j, 0] = t[k]
                for i in range(4):
                    hist[j, 1 + i] = omega[k, i]
        else:
            dt = t[k] - state[0]
            fxp, fyp, rp = state[2], state[3], state[4]
            vx, vy = x[VX], x[VY]
            # Prediction: v̇x = f_x − b + r v_y, v̇y = f_y − r v_x (inputs of the previous sample).
            x[VX] = vx + dt * (fxp - x[BX] + rp * vy)
            x[VY] = vy + dt * (fyp - rp * vx)
            for i in range(3):
                for j in range(3):
                    F[i, j] = 1.0 if i == j else 0.0
            F[VX, VY] = dt * rp
            F[VX, BX] = -dt
            F[VY, VX] = -dt * rp
            for i in range(3):  # FP
                for j in range(3):
                    acc = 0.0
                    for q in range(3):
                        acc += F[i, q] * P[q, j]
                    FP[i, j] = acc
            for i in range(3):  # P = FP Fᵀ
                for j in range(3):
                    acc = 0.0
                    for q in range(3):
                        acc += FP[i, q] * F[j, q]
                    P[i, j] = acc
            P[VX, VX] += q_vx * dt
            P[VY, VY] += q_vy * dt
            P[BX, BX] += q_b * dt
        span = t[k] - hist[0, 0]
        r_now = yaw_rate[k]
        # Wheel speeds mapped to the CG, trusted by their evidence of slip.
        accepted = 0
        for i in range(4):
            c, s = np.cos(delta[k, i]), np.sin(delta[k, i])
            vxw = x[VX] - r_now * yw[i]
            vyw = x[VY] + r_now * xw[i]
            vyt = -vxw * s + vyw * c
            v_meas = radius * omega[k, i] * c - vyt * s + r_now * yw[i]
            omega_dot = (omega[k, i] - hist[0, 1 + i]) / span if span > 0 else 0.0
            acc_err = abs(radius * omega_dot - f_x[k] + x[BX])
            sig = np.sqrt(r_w) + k_mu * abs(mu_x[k, i]) * abs(x[VX]) + k_acc * acc_err
            innov_pred = v_meas - x[VX]
            if (torque[k, i] > 0 and innov_pred > 0) or (torque[k, i] < 0 and innov_pred < 0):
                sig *= 1.0 + (innov_pred / s_sign) ** 2
            h[:] = 0.0
            h[VX] = 1.0
            res = _scalar_update(x, P, h, v_meas, sig * sig, gate, ph)
            out_trust[k, i] = np.inf if np.isnan(res) else sig
            wheel_v[i] = v_meas
            if not np.isnan(res):
                accepted += 1
        # Recovery: every wheel rejected although none shows evidence of slip means the
        # filter, not the wheels, has drifted. After ``window`` such samples, restart v_x
        # from the median wheel speed (an ESC unit's reference-speed reset).
        state[5] = state[5] + 1.0 if accepted == 0 else 0.0
        if state[5] >= m:
            x[VX] = np.median(wheel_v)
            for j in range(3):
                P[VX, j] = 0.0
                P[j, VX] = 0.0
            P[VX, VX] = r_w
            state[5] = 0.0
        # The bias is physically bounded (sensor bias plus a grade of at most ~5 %): a larger
        # value means slip or a spinning car is being explained away as bias.
        x[BX] = min(max(x[BX], -bias_max), bias_max)
        # Extra CG-speed measurements (fusion with the corner-based estimators).
        for j in range(extra_v.shape[1]):
            if not np.isnan(extra_v[k, j]):
                h[:] = 0.0
                h[VX] = 1.0
                _scalar_update(x, P, h, extra_v[k, j], extra_var[k, j], gate, ph)
        # v_y ≈ r l_r + v_x α_r with the rear slip angle α_r = −F_yr/C_yr (weak near the limit).
        sig_vy = np.sqrt(r_vy) + k_vy * abs(f_y[k])
        h[:] = 0.0
        h[VY] = 1.0
        _scalar_update(x, P, h, r_now * lr + x[VX] * rear_slip[k], sig_vy * sig_vy, 1e9, ph)
        # History for ω̇, and inputs held over the next interval.
        for j in range(m - 1):
            for col in range(5):
                hist[j, col] = hist[j + 1, col]
        hist[m - 1, 0] = t[k]
        for i in range(4):
            hist[m - 1, 1 + i] = omega[k, i]
        state[0] = t[k]
        state[2] = f_x[k]
        state[3] = f_y[k]
        state[4] = r_now
        out_v[k, 0] = x[VX]
        out_v[k, 1] = x[VY]
        out_sig[k, 0] = np.sqrt(max(P[VX, VX], 0.0))
        out_sig[k, 1] = np.sqrt(max(P[VY, VY], 0.0))
        out_bias[k] = x[BX]


class ReferenceFilter:
    """Stateful wrapper of :func:`reference_kernel` (``reset``, ``advance``)."""

    def __init__(self, radius: float, lr: float, xw: np.ndarray, yw: np.ndarray,
                 params: ReferenceParams | None = None) -> None:
        self.radius = radius
        self.lr = lr
        self.xw = np.ascontiguousarray(xw, dtype=float)
        self.yw = np.ascontiguousarray(yw, dtype=float)
        self.params = params or ReferenceParams()
        p = self.params
        self._prm = np.array([p.q_vx, p.q_vy, p.q_bias, p.r_wheel, p.k_mu, p.k_acc, p.slip_sign,
                              p.gate, p.r_vy, p.k_vy, p.bias_max])
        self.reset()

    def reset(self) -> None:
        self._x = np.zeros(3)
        self._P = np.zeros((3, 3))
        self._hist = np.zeros((self.params.window, 5))
        self._state = np.zeros(6)

    def advance(self, t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                rear_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray, yaw_rate: np.ndarray,
                delta: np.ndarray,
                extra_v: np.ndarray | None = None,
                extra_var: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Process a chunk; returns v (n, 2) [v_x, v_y] m/s, sigma (n, 2), bias (n,), trust (n, 4).

        ``rear_slip`` (n,) is the rear-axle slip angle estimate −F_yr/C_yr in rad.
        """
        n = t.shape[0]
        if extra_v is None or extra_var is None:
            extra_v = np.full((n, 0), np.nan)
            extra_var = np.full((n, 0), np.nan)
        v = np.empty((n, 2))
        sig = np.empty((n, 2))
        bias = np.empty(n)
        trust = np.empty((n, 4))
        reference_kernel(t, omega, torque, mu_x, np.ascontiguousarray(rear_slip), f_x, f_y,
                         yaw_rate, delta,
                         np.ascontiguousarray(extra_v), np.ascontiguousarray(extra_var),
                         self.radius, self.lr, self.xw, self.yw, self._prm, self._x, self._P, self._hist,
                         self._state, v, sig, bias, trust)
        return {"v": v, "sigma": sig, "bias": bias, "trust": trust}
