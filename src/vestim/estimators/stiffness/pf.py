"""Algorithm 1 of 002: noise-adaptive marginalised particle filter for stiffness and state.

Each particle i carries the vehicle state x^i, the NiW statistics (μ̂^i, Λ^i)
of the stiffness deviation w (002 eq. (19)–(20); γ and ν evolve identically
for all particles and are shared scalars), the mean b^i and covariance P^i of
its own bias Kalman filter (eq. (29)–(30)) and a log weight. One step k of
:func:`alg1_kernel`:

1. (Algorithm 1, lines 2–5) per particle: the moment-matched Student-t of the
   total measurement noise (eq. (35)) gives the weight update (eq. (36)); the
   joint t of (w, ē) conditioned on the innovation (Theorem 1, eq. (39)–(41))
   is the predictive of w_k, from which w_k^i is drawn; when the filter is
   active the statistics are updated with that draw (eq. (19)).
2. (lines 6–10) normalise, N_eff, systematic resampling when N_eff ≤ N_thr,
   copying states, statistics and biases.
3. (lines 11–13) state estimate (eq. (42)), parameter estimate (eq. (26)–(27)).
4. (lines 14–20) per particle: bias update (eq. (30)), statistics prediction
   (eq. (20)), state prediction x_{k+1} = f + g w_k (eq. (9)), bias prediction (29).

Choices where the paper is silent or ambiguous (also in docs/methods_stiffness.md):

* Order. Algorithm 1 updates the statistics (line 4) before it draws w_k
  (line 17), but eq. (19e) needs the draw, and the text after Theorem 1 uses
  the same draw for eq. (19) and for the state prediction. We draw w_k^i from
  eq. (39) at line 4, use it for eq. (19) and keep f + g w_k^i for line 18;
  resampling copies that prediction with the statistics.
* Activation (Sec. V). On a step that is not active the statistics are
  frozen: neither eq. (19) nor the forgetting of eq. (20) is applied. Weights,
  draws, bias filter and state prediction run as usual.
* Forgetting per second. λ of eq. (20) is a per-step factor, and 002 does not
  state its sample rate (the estimator runs "at several tens of Hz", Sec. IV-B,
  VII-B). ``forgetting`` is λ per ``forgetting_period`` seconds; a step of
  length T_s applies λ^(T_s/period). With the period equal to the log's step
  this is 002's per-step λ.
* Projection (Sec. V). Draws w^i and means μ̂^i are clipped to the bounds
  [lo, hi] of the deviation after every draw and update.
* Model error (not in 002). Eq. (9) has no state noise besides w. On the
  double-track plant (load transfer, roll, Magic-Formula curvature, tire
  relaxation and carcass damping) the single-track model misses a_y by
  0.05–0.1 m/s² rms with spikes of ~1 m/s² at steering steps, and without
  state noise the particle cloud collapses (N_eff → 1) and the parameter
  statistics absorb the misfit. ``model_error`` adds white acceleration noise
  (m/s², m/s², rad/s², held over one step) to the state prediction; zero
  reproduces eq. (9) exactly. The default has none on v_x, where it lets each
  particle trade v_x (hence its slip) against its C^x (docs/methods_stiffness.md).
* The χ²_ν* variable of the Student-t draw (w = μ* + L n √(ν*/χ²)) uses the
  Wilson–Hilferty approximation χ²_ν/ν ≈ (1 − 2/(9ν) + z √(2/(9ν)))³, z ~ N(0, 1),
  instead of a gamma variate (one normal instead of a rejection sampler). Its
  0.1–99.9 % quantiles are within 1.4 % of the exact ones at ν = 21 (ν* right
  after start, ν_0 = 20) and within 0.08 % at the steady ν* ≈ 100 (λ = 0.99).
* Settling (Sec. V activation). During the first ``settle_time`` of a log the
  state posterior is still converging from P_0; statistics and bias filter are
  frozen then (``settled`` = False), see :class:`~vestim.estimators.stiffness.config.StiffnessConfig`.
* Bias filter. Eq. (30) with the state uncertainty of the cloud added to S; see
  :func:`bias_kalman`.
* Gyro look-ahead (``gyro_lookahead``, default on). As printed, w_k is conditioned on
  y_k, whose gyro row of d is zero: the yaw dynamics, which in a steering step are the
  only measurement of the front/rear split of the cornering stiffness, reach the
  statistics only through the weights of the next step. The gyro sample of step k + 1
  measures ψ̇_{k+1} = f_ψ̇(x_k) + g_ψ̇ w_k + b_ψ̇ + e (eq. (9)), affine in w_k, so Theorem 1
  applies unchanged to [a_x,k, a_y,k, ψ̇_{k+1}]: the gyro row of d is the yaw row of g,
  its noise R_ψ̇ + P_ψ̇ + (T_s σ_me,ψ̇)², and Λ̃_ē of eq. (35) a full 3 × 3. The same
  measurement weighs the particles (eq. (36)); the gyro sample of step k has then been
  used at step k − 1 and is not used again. Eq. (30)'s gyro residual is that of the
  look-ahead row with μ̂_{k|k} (and g_ψ̇ Σ̂ g_ψ̇ᵀ in S): the residual of ψ̇_k after the draw
  would no longer see an error of b̂_ψ̇, since the cloud then follows gyro − b̂_ψ̇.
* Estimates. Lines 11–13 are evaluated on the weighted particles of line 6,
  before the resampling of lines 8–10: the same sums (42), (26)–(27) of the same
  posterior, without the extra Monte-Carlo variance that resampling adds
  (Doucet & Johansen, 002 ref. [17]). They are outputs and do not feed back,
  except the cloud covariance of the bias filter (:func:`bias_kalman`).

Structure used for speed (the arithmetic is that of :mod:`vestim.filters.niw`
written out for this sparsity; ``tests/estimators/stiffness/test_pf.py`` checks
steps against a composition of the generic functions):

* The gyro row of d is zero, and R, Q and P_0 have no accelerometer–gyro
  coupling, so every P^i stays block-diagonal (2 × 2 accelerometer block, scalar
  gyro): Λ̃_ē of eq. (35) is block-diagonal and all inverses are 2 × 2. The joint
  t still has n_e = 3 (the gyro noise shares the t scale variable, so it enters
  the Mahalanobis distance and ν* = ν̃ + 3).
* Each particle is one row of a packed array (columns ``C_*``); symmetric
  matrices are stored packed: Λ as [Λ00, Λ01, Λ02, Λ11, Λ12, Λ22], P as
  [P_xx, P_xy, P_yy, P_ψψ]. Resampling copies rows into a second buffer.
* One pass over the particles per step: lines 14–20 of step k − 1 (they need
  nothing from the other particles once the cloud covariance of step k − 1 is
  known) run in the same loop as lines 2–5 of step k. What lines 14–20 need from
  lines 2–5 is computed there: the prediction f + g w_k (line 18 without the
  model-error noise), the innovation of eq. (30) and d Σ̂_{k|k} dᵀ, which follows
  from the d Λ_{k|k−1} dᵀ of eq. (35) and the rank-one update (19d). The
  forgetting (20) of Λ is applied right after (19), so the statistics in the
  array are S_{k+1|k}. A second pass normalises the weights (line 6) and
  accumulates N_eff and all moments of lines 11–13.
* Random numbers come from :mod:`~vestim.estimators.stiffness.draws` (an inline
  stream seeded from the caller's Generator): at the start of each step one block
  of normals per particle (columns ``D_*``: the three of the t draw of w_k, the
  Wilson–Hilferty one, then the model-error noise of step k − 1), one uniform per
  resampling.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.estimators.stiffness.draws import fill_normals, uniform
from vestim.estimators.stiffness.model import (
    M_AX,
    M_AY,
    M_YAW_RATE,
    U_DELTA,
    U_DT,
    U_OMEGA_F,
    U_OMEGA_R,
    VX,
    VY,
    W_CX,
    W_CYF,
    W_CYR,
    YAW_RATE,
    terms,
)
from vestim.filters.kalman import direct_update21
from vestim.filters.resampling import systematic_resample

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}
_FAST: dict[str, Any] = {**_JIT, "fastmath": {"contract", "arcp", "nsz"}}
"""Fused multiply-add, reciprocal multiplication and signed-zero freedom only: the
kernel relies on inf and NaN semantics (a particle with a non-finite weight is
dropped), so ``nnan``/``ninf`` stay off."""

# Packed symmetric layouts.
L00, L01, L02, L11, L12, L22 = range(6)
"""Λ (3 × 3, w space) packed row-wise upper triangle."""
PXX, PXY, PYY, PRR = range(4)
"""P (bias covariance): accelerometer 2 × 2 block and the gyro variance."""
N_LAM = 6
N_PB = 4
N_TERMS = 14
"""Number of values returned by :func:`~vestim.estimators.stiffness.model.terms`."""

# Columns of the packed particle array (one row per particle).
C_X = 0
"""x_k = [v_x, v_y, ψ̇] (m/s, m/s, rad/s), 3 columns."""
C_XN = 3
"""f(x_k) + g(x_k) w_k, the prediction of eq. (9) before the model-error noise, 3 columns."""
C_MU = 6
"""μ̂ of the NiW statistics (N per unit slip, N/rad, N/rad), 3 columns."""
C_LAM = 9
"""Λ of the NiW statistics, packed (``L00`` …), 6 columns."""
C_B = 15
"""Bias mean b = [b_ax, b_ay, b_ψ̇] (m/s², m/s², rad/s), 3 columns."""
C_PB = 18
"""Bias covariance P, packed (``PXX`` …), 4 columns."""
C_EB = 22
"""Innovation y − h − d μ̂_{k|k} − b_{k|k−1} of eq. (30), 3 columns."""
C_SB = 25
"""d Σ̂_{k|k} dᵀ of eq. (30), packed like P (``PXX``, ``PXY``, ``PYY``, ``PRR``), 4 columns; the
gyro entry is non-zero only with the gyro look-ahead (g_ψ̇ Σ̂ g_ψ̇ᵀ plus the model-error variance)."""
N_COL = 29

# Columns of the per-step block of standard normals (one row per particle).
D_W = 0
"""The three normals of the Student-t draw of w_k (eq. (39))."""
D_CHI = 3
"""The normal of the Wilson–Hilferty χ² of that draw."""
D_ME = 4
"""The normals of the model-error noise, [v_y, ψ̇] if either is non-zero, then v_x if non-zero."""

CHOL_FLOOR = 1e-12
"""Relative floor on a Cholesky pivot (round-off on a semi-definite scale matrix)."""


class MeasVec(NamedTuple):
    """A vector in the measurement space [a_x, a_y, ψ̇] (m/s², m/s², rad/s): a bias or a residual."""

    ax: float
    ay: float
    yaw_rate: float


class MeasCov(NamedTuple):
    """A covariance in the measurement space, packed like P (``PXX`` …): the accelerometer
    2 × 2 block (m²/s⁴) and the gyro variance (rad²/s²)."""

    xx: float
    xy: float
    yy: float
    rr: float


class AccelCov(NamedTuple):
    """The accelerometer 2 × 2 block (m²/s⁴) of a measurement covariance."""

    xx: float
    xy: float
    yy: float


class PFParams(NamedTuple):
    """What :func:`alg1_kernel` holds fixed over a run (packed by
    :meth:`~vestim.estimators.stiffness.estimator.NoiseAdaptivePF.params`).

    Attributes:
        p: model parameters (``model.P_*``).
        r_pk, q_pk: R and Q of eq. (11)–(12), packed like P (m²/s⁴, rad²/s²; Q per step).
        bias_inflation: factor (≥ 1) on the residual covariance R + d Σ̂ dᵀ + H P_x Hᵀ of the
            bias update (30) only (not of the weights): the residuals are correlated over
            about ``bias_inflation`` steps (see :func:`bias_kalman`); 1 is eq. (30).
        lo, hi: (3,) bounds of the deviation w (projection, Sec. V; N per unit slip, N/rad, N/rad).
        forgetting: λ of eq. (20) per ``forgetting_period`` seconds (see the module
            docstring); a step of length T_s forgets by λ^(T_s/period).
        forgetting_period: s.
        n_thr: N_thr of Algorithm 1, line 8 (particles).
        model_error: (3,) std of the acceleration noise added to the state prediction
            (m/s², m/s², rad/s²; see the module docstring), zeros for eq. (9) as printed.
        gyro_lookahead: condition w_k (Theorem 1) and weigh the particles (eq. (36)) on
            [a_x,k, a_y,k, ψ̇_{k+1}] instead of y_k = [a_x,k, a_y,k, ψ̇_k]: the gyro sample
            of step k + 1 measures ψ̇_{k+1} = f_ψ̇ + g_ψ̇ w_k (eq. (9)), so its row of d is
            the yaw row of g and its noise R_ψ̇ + P_ψ̇ + (T_s σ_me,ψ̇)² (module docstring,
            *Gyro look-ahead*). False is Algorithm 1 as printed.
    """

    p: np.ndarray
    r_pk: np.ndarray
    q_pk: np.ndarray
    bias_inflation: float
    lo: np.ndarray
    hi: np.ndarray
    forgetting: float
    forgetting_period: float
    n_thr: float
    model_error: np.ndarray
    gyro_lookahead: bool


class PFState(NamedTuple):
    """What :func:`alg1_kernel` advances in place.

    Attributes:
        part: (N, ``N_COL``) particles (:func:`pack_particles`) holding x_k, S_{k|k−1},
            b_{k|k−1}, P_{k|k−1}.
        logw: (N,) log weights.
        shared: [γ_{k|k−1}, ν_{k|k−1}] (shared by all particles).
        rng_state: (4,) uint64 state of the random stream (:mod:`~vestim.estimators.stiffness.draws`,
            seeded from a ``numpy.random.Generator`` by ``draws.seed_state``).
    """

    part: np.ndarray
    logw: np.ndarray
    shared: np.ndarray
    rng_state: np.ndarray


class SeriesInputs(NamedTuple):
    """The time series the particle filters read (:func:`alg1_kernel`,
    :func:`~vestim.estimators.stiffness.augpf.augpf_kernel`), one row per step.

    Attributes:
        y: (K, 3) measurements [a_x, a_y, ψ̇] (m/s², m/s², rad/s; roll/pitch compensated).
        u: (K, 4) inputs [δ rad, ω_f rad/s, ω_r rad/s, T_s s].
        active: (K,) bool, statistics update and forgetting on (Sec. V; Algorithm 1 only).
        bias_on: (K,) bool; where False the bias filter is frozen (no eq. (29)–(30)).
    """

    y: np.ndarray
    u: np.ndarray
    active: np.ndarray
    bias_on: np.ndarray


class Estimates(NamedTuple):
    """The particle filters' outputs, one row per step (written by the kernels).

    Attributes:
        x_hat, x_var: (K, 3) weighted mean and variance of x_k = [v_x, v_y, ψ̇] (eq. (42);
            m/s, m/s, rad/s and their squares).
        w_hat: (K, 3) μ̂_k (eq. (27a)). w_cov: (K, 3, 3) Σ̂_k (eq. (27b)).
        b_hat: (K, 3) weighted mean of b_{k|k} (m/s², m/s², rad/s). ess: (K,) N_eff.
    """

    x_hat: np.ndarray
    x_var: np.ndarray
    w_hat: np.ndarray
    w_cov: np.ndarray
    b_hat: np.ndarray
    ess: np.ndarray


def new_estimates(k: int) -> Estimates:
    """Uninitialised :class:`Estimates` for ``k`` steps."""
    return Estimates(np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3, 3)),
                     np.empty((k, 3)), np.empty(k))


def pack_particles(x: np.ndarray, mu: np.ndarray, lam: np.ndarray, b: np.ndarray,
                   pb: np.ndarray) -> np.ndarray:
    """Packed particle array (N, ``N_COL``) for :func:`alg1_kernel` from per-quantity arrays.

    Args:
        x: (N, 3) states. mu: (N, 3) and lam: (N, 6) NiW statistics μ̂, Λ (packed).
        b: (N, 3) bias means. pb: (N, 4) bias covariances (packed).
    """
    n = x.shape[0]
    part = np.zeros((n, N_COL))
    part[:, C_X:C_X + 3] = x
    part[:, C_MU:C_MU + 3] = mu
    part[:, C_LAM:C_LAM + N_LAM] = lam
    part[:, C_B:C_B + 3] = b
    part[:, C_PB:C_PB + N_PB] = pb
    return part


@njit(**_JIT)
def chol3(a00: float, a01: float, a02: float, a11: float, a12: float,
          a22: float) -> tuple[float, float, float, float, float, float]:
    """Lower Cholesky factor (l00, l10, l20, l11, l21, l22) of a symmetric 3 × 3 matrix.

    A pivot below ``CHOL_FLOOR`` times the largest diagonal entry is raised to it.
    """
    floor = CHOL_FLOOR * max(a00, a11, a22, 1e-300)
    l00 = math.sqrt(max(a00, floor))
    i00 = 1.0 / l00
    l10 = a01 * i00
    l20 = a02 * i00
    l11 = math.sqrt(max(a11 - l10 * l10, floor))
    l21 = (a12 - l20 * l10) / l11
    l22 = math.sqrt(max(a22 - l20 * l20 - l21 * l21, floor))
    return l00, l10, l20, l11, l21, l22


@njit(**_JIT)
def sym3_mv(s00: float, s01: float, s02: float, s11: float, s12: float, s22: float,
            x0: float, x1: float, x2: float) -> tuple[float, float, float]:
    """S x for a symmetric 3 × 3 S given by its upper triangle."""
    return (s00 * x0 + s01 * x1 + s02 * x2, s01 * x0 + s11 * x1 + s12 * x2,
            s02 * x0 + s12 * x1 + s22 * x2)


@njit(**_JIT)
def bias_kalman(b: MeasVec, pb: MeasCov, e: MeasVec, s: AccelCov, r: MeasCov,
                u: MeasCov) -> tuple[MeasVec, MeasCov]:
    """Kalman update of one particle's bias, 002 eq. (30), on scalars.

    ``b``, ``pb``: the bias b_{k|k−1} and its covariance P_{k|k−1}. Innovation ``e`` =
    y − h − d μ̂_{k|k} − b_{k|k−1}; ``s`` = d Σ̂_{k|k} dᵀ (accelerometer block; a gyro entry
    goes into ``u.rr``); ``r`` = R and ``u`` = H P_x Hᵀ. S = P + R + d Σ̂ dᵀ + H P_x Hᵀ,
    K = P S⁻¹, b ← b + K e and P ← P − K S Kᵀ = P − P S⁻¹ P.

    Two deviations from the printed eq. (30): 002 prints P − K S⁻¹ Kᵀ, which is not
    the Kalman covariance update (we use the standard form); and eq. (30) treats the
    particle's state as exact. While the particle cloud is still wide (after
    initialisation from P_0, or after a stiffness change) each particle's residual is
    dominated by its own state error, and with S = P + R + dΣ̂dᵀ the bias absorbs it
    (we saw a_y bias estimates of 1.4 m/s² against a 0.05 m/s² prior). Adding the
    posterior state covariance P_x of the cloud, mapped through H = ∂[a_x, a_y, ψ̇]/∂x
    at the weighted mean, keeps the bias filter out of the state transient and
    vanishes once the cloud has converged. The update itself is
    :func:`vestim.filters.kalman.direct_update21` (H = I, block-diagonal P and S).

    Returns:
        (b_{k|k}, P_{k|k}).
    """
    b0, b1, b2, q00, q01, q11, q22 = direct_update21(
        b.ax, b.ay, b.yaw_rate, pb.xx, pb.xy, pb.yy, pb.rr,
        pb.xx + r.xx + s.xx + u.xx, pb.xy + r.xy + s.xy + u.xy, pb.yy + r.yy + s.yy + u.yy,
        pb.rr + r.rr + u.rr, e.ax, e.ay, e.yaw_rate)
    return MeasVec(b0, b1, b2), MeasCov(q00, q01, q11, q22)


@njit(**_JIT)
def bias_update(b: np.ndarray, pb: np.ndarray, e0: float, e1: float, e2: float,
                s00: float, s01: float, s11: float, r: np.ndarray, x_unc: np.ndarray) -> None:
    """:func:`bias_kalman` in place on ``b`` (3,) and ``pb`` (4,); ``r``, ``x_unc`` packed like ``pb``."""
    nb, npb = bias_kalman(MeasVec(b[M_AX], b[M_AY], b[M_YAW_RATE]),
                          MeasCov(pb[PXX], pb[PXY], pb[PYY], pb[PRR]), MeasVec(e0, e1, e2),
                          AccelCov(s00, s01, s11), MeasCov(r[PXX], r[PXY], r[PYY], r[PRR]),
                          MeasCov(x_unc[PXX], x_unc[PXY], x_unc[PYY], x_unc[PRR]))
    b[M_AX], b[M_AY], b[M_YAW_RATE] = nb.ax, nb.ay, nb.yaw_rate
    pb[PXX], pb[PXY], pb[PYY], pb[PRR] = npb.xx, npb.xy, npb.yy, npb.rr


@njit(**_JIT)
def weighted_state_moments(q: np.ndarray, x: np.ndarray, mean: np.ndarray, var: np.ndarray) -> None:
    """Weighted mean and variance of each column of ``x`` (N, n) (002 eq. (42))."""
    n = x.shape[1]
    for a in range(n):
        s = 0.0
        for i in range(q.shape[0]):
            s += q[i] * x[i, a]
        mean[a] = s
        s2 = 0.0
        for i in range(q.shape[0]):
            e = x[i, a] - s
            s2 += q[i] * e * e
        var[a] = s2


@njit(**_JIT)
def accel_jacobian(vx: float, vy: float, r: float, delta: float, sin_d: float, cos_d: float,
                   om_f: float, om_r: float, ts: float,
                   p: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """∂[a_x, a_y]/∂[v_x, v_y, ψ̇] of eq. (12) at nominal stiffness, by central differences.

    Returns:
        (∂a_x/∂v_x, ∂a_x/∂v_y, ∂a_x/∂ψ̇, ∂a_y/∂v_x, ∂a_y/∂v_y, ∂a_y/∂ψ̇).
    """
    h0 = 1e-3
    h1 = 1e-4
    h2 = 1e-5
    tp = terms(vx + h0, vy, r, delta, sin_d, cos_d, om_f, om_r, ts, p)
    tm = terms(vx - h0, vy, r, delta, sin_d, cos_d, om_f, om_r, ts, p)
    x0 = (tp[3] - tm[3]) / (2.0 * h0)
    y0 = (tp[4] - tm[4]) / (2.0 * h0)
    tp = terms(vx, vy + h1, r, delta, sin_d, cos_d, om_f, om_r, ts, p)
    tm = terms(vx, vy - h1, r, delta, sin_d, cos_d, om_f, om_r, ts, p)
    x1 = (tp[3] - tm[3]) / (2.0 * h1)
    y1 = (tp[4] - tm[4]) / (2.0 * h1)
    tp = terms(vx, vy, r + h2, delta, sin_d, cos_d, om_f, om_r, ts, p)
    tm = terms(vx, vy, r - h2, delta, sin_d, cos_d, om_f, om_r, ts, p)
    x2 = (tp[3] - tm[3]) / (2.0 * h2)
    y2 = (tp[4] - tm[4]) / (2.0 * h2)
    return x0, x1, x2, y0, y1, y2


@njit(**_JIT)
def project_state_cov(hx: tuple[float, float, float, float, float, float], c00: float,
                      c01: float, c02: float, c11: float, c12: float,
                      c22: float) -> tuple[float, float, float, float]:
    """H P_x Hᵀ of the measurement [a_x, a_y, ψ̇], packed like P (see :func:`bias_kalman`).

    ``hx`` from :func:`accel_jacobian`; (c..) the packed state covariance P_x. The
    yaw-rate row of H is [0, 0, 1].
    """
    h00, h01, h02, h10, h11, h12 = hx
    # P_x Hᵀ columns
    a0 = c00 * h00 + c01 * h01 + c02 * h02
    a1 = c01 * h00 + c11 * h01 + c12 * h02
    a2 = c02 * h00 + c12 * h01 + c22 * h02
    b0 = c00 * h10 + c01 * h11 + c02 * h12
    b1 = c01 * h10 + c11 * h11 + c12 * h12
    b2 = c02 * h10 + c12 * h11 + c22 * h12
    return (h00 * a0 + h01 * a1 + h02 * a2, h10 * a0 + h11 * a1 + h12 * a2,
            h10 * b0 + h11 * b1 + h12 * b2, c22)


@njit(**_JIT)
def state_uncertainty(q: np.ndarray, x: np.ndarray, x_mean: np.ndarray, delta: float,
                      sin_d: float, cos_d: float, om_f: float, om_r: float, ts: float,
                      p: np.ndarray, out: np.ndarray) -> None:
    """H P_x Hᵀ of the measurement [a_x, a_y, ψ̇] into ``out``, packed like P.

    P_x is the weighted covariance of the particle states ``x`` (N, 3) about ``x_mean``,
    H = ∂h/∂x at ``x_mean`` (:func:`accel_jacobian`).
    """
    c00 = c01 = c02 = c11 = c12 = c22 = 0.0
    for i in range(q.shape[0]):
        e0 = x[i, VX] - x_mean[VX]
        e1 = x[i, VY] - x_mean[VY]
        e2 = x[i, YAW_RATE] - x_mean[YAW_RATE]
        qi = q[i]
        c00 += qi * e0 * e0
        c01 += qi * e0 * e1
        c02 += qi * e0 * e2
        c11 += qi * e1 * e1
        c12 += qi * e1 * e2
        c22 += qi * e2 * e2
    hx = accel_jacobian(x_mean[VX], x_mean[VY], x_mean[YAW_RATE], delta, sin_d, cos_d, om_f,
                        om_r, ts, p)
    out[PXX], out[PXY], out[PYY], out[PRR] = project_state_cov(hx, c00, c01, c02, c11, c12, c22)


@njit(**_FAST)
def alg1_kernel(prm: PFParams, st: PFState, inp: SeriesInputs, out: Estimates) -> int:
    """Run Algorithm 1 of 002 over the K steps of ``inp``; ``st`` is advanced in place.

    Args:
        prm: the run's parameters (:class:`PFParams`).
        st: particles, log weights, [γ, ν] and the random stream (:class:`PFState`): on entry
            x_k, S_{k|k−1}, b_{k|k−1}, P_{k|k−1} of the first step, on return those of step K;
            the stream advanced by every normal and the resampling uniforms.
        inp: y, u, active, bias_on over the K steps (:class:`SeriesInputs`).
        out: ← the estimates of each step (:class:`Estimates`; ``ess`` is N_eff of line 7).

    Returns:
        The number of resampling events.
    """
    y, u, active, bias_on = inp.y, inp.u, inp.active, inp.bias_on
    p, r_pk, q_pk, lo, hi = prm.p, prm.r_pk, prm.q_pk, prm.lo, prm.hi
    bias_inflation = prm.bias_inflation
    forgetting, forgetting_period = prm.forgetting, prm.forgetting_period
    n_thr = prm.n_thr
    model_error = prm.model_error
    part, logw, shared, rng_state = st.part, st.logw, st.shared, st.rng_state
    x_hat, x_var, w_hat, w_cov, b_hat, ess = out.x_hat, out.x_var, out.w_hat, out.w_cov, out.b_hat, out.ess
    n_part = part.shape[0]
    n_steps = y.shape[0]
    if n_steps == 0:
        return 0
    spare = np.empty_like(part)
    q = np.empty(n_part)
    idx = np.empty(n_part, dtype=np.int64)
    x_unc = np.zeros(N_PB)
    me_lat = model_error[VY] > 0.0 or model_error[YAW_RATE] > 0.0
    c_vx = (D_ME + 2 if me_lat else D_ME) if model_error[VX] > 0.0 else -1
    nrm = np.empty((n_part, max(c_vx + 1, D_ME + 2 if me_lat else D_ME)))
    log_n = math.log(n_part)
    n_resampled = 0
    gamma = shared[0]
    nu = shared[1]
    me_vx = model_error[VX]
    me_vy = model_error[VY]
    me_r = model_error[YAW_RATE]
    look = prm.gyro_lookahead
    r00 = r_pk[PXX]
    r01 = r_pk[PXY]
    r11 = r_pk[PYY]
    rrr = r_pk[PRR]
    bi = max(bias_inflation, 1.0)
    br = MeasCov(bi * r00, bi * r01, bi * r11, bi * rrr)
    lo0, lo1, lo2 = lo[W_CX], lo[W_CYF], lo[W_CYR]
    hi0, hi1, hi2 = hi[W_CX], hi[W_CYF], hi[W_CYR]
    # q holds the normalised weights after the previous step's resampling (for b_hat)
    top = -math.inf
    for i in range(n_part):
        top = max(top, logw[i])
    s = 0.0
    for i in range(n_part):
        q[i] = math.exp(logw[i] - top)
        s += q[i]
    for i in range(n_part):
        q[i] /= s
    ts_prev = 0.0
    # One pass more than steps: the last pass only finishes step K − 1 (lines 14–20).
    for k in range(n_steps + 1):
        last = k == n_steps
        kk = min(k, n_steps - 1)
        delta = u[kk, U_DELTA]
        sd = math.sin(delta)
        cd = math.cos(delta)
        om_f = u[kk, U_OMEGA_F]
        om_r = u[kk, U_OMEGA_R]
        ts = u[kk, U_DT]
        y0 = y[kk, M_AX]
        y1 = y[kk, M_AY]
        y2 = y[kk, M_YAW_RATE]
        look_k = look and k + 1 < n_steps
        y2n = y[k + 1, M_YAW_RATE] if look_k else y2
        me_r2 = (ts * me_r) ** 2 if look_k else 0.0
        act = active[kk] and not last
        finish = k > 0
        finish_bias = finish and bias_on[k - 1]
        lam_k = forgetting ** (ts / forgetting_period)   # λ of eq. (20) for this step
        dof = nu - 2.0              # ν̃ = ν − n_w + 1
        inv_dof = 1.0 / dof
        c1 = (1.0 + gamma) * inv_dof    # scale of the w predictive (21); also S_w of the joint t
        c2 = (dof - 2.0) * inv_dof      # moment matching of R + P (35)
        dof_c = dof + 3.0           # ν* = ν̃ + n_e (41)
        half_dof_c = 0.5 * dof_c
        c_scale = c1 / dof_c        # S_w of (41) = (ν̃ + maha)/ν* · c1 · (Λ − …)
        wh_a = 2.0 / (9.0 * dof_c)
        wh_b = math.sqrt(wh_a)
        if act:
            g_post = gamma / (1.0 + gamma)
            c_upd = 1.0 / (1.0 + gamma)
            nu_post = nu + 1.0
            lam_f = lam_k
        else:
            g_post = 0.0
            c_upd = 0.0
            nu_post = nu
            lam_f = 1.0
        inv_c_post = 1.0 / (nu_post - 4.0)    # Σ̂_{k|k} = Λ_{k|k}/(ν_{k|k} − n_w − 1)
        top = -math.inf
        bh0 = 0.0
        bh1 = 0.0
        bh2 = 0.0
        fill_normals(rng_state, nrm)
        bu00 = bi * x_unc[PXX]
        bu01 = bi * x_unc[PXY]
        bu11 = bi * x_unc[PYY]
        burr = bi * x_unc[PRR]
        for i in range(n_part):
            if finish:
                # ---- lines 14–20 of step k − 1 (their turn comes before lines 2–5 of step k):
                # bias update (30) with the innovation and d Σ̂ dᵀ stored by lines 2–5, bias
                # prediction (29), and x_k = f + g w_{k−1} plus the model-error noise, drawn
                # only where non-zero (v_y, ψ̇ from nrm[i, D_ME:D_ME + 2], v_x from nrm[i, c_vx]).
                # Written out here: a helper taking the arrays costs reference counting per call.
                if finish_bias:
                    nb, npb = bias_kalman(
                        MeasVec(part[i, C_B], part[i, C_B + 1], part[i, C_B + 2]),
                        MeasCov(part[i, C_PB + PXX], part[i, C_PB + PXY], part[i, C_PB + PYY],
                                part[i, C_PB + PRR]),
                        MeasVec(part[i, C_EB], part[i, C_EB + 1], part[i, C_EB + 2]),
                        AccelCov(bi * part[i, C_SB + PXX], bi * part[i, C_SB + PXY],
                                 bi * part[i, C_SB + PYY]), br,
                        MeasCov(bu00, bu01, bu11, burr + bi * part[i, C_SB + PRR]))
                    part[i, C_B] = nb.ax
                    part[i, C_B + 1] = nb.ay
                    part[i, C_B + 2] = nb.yaw_rate
                    part[i, C_PB + PXX] = npb.xx + q_pk[PXX]
                    part[i, C_PB + PXY] = npb.xy + q_pk[PXY]
                    part[i, C_PB + PYY] = npb.yy + q_pk[PYY]
                    part[i, C_PB + PRR] = npb.rr + q_pk[PRR]
                xn0 = part[i, C_XN + VX]
                xn1 = part[i, C_XN + VY]
                xn2 = part[i, C_XN + YAW_RATE]
                if me_lat:
                    xn1 += ts_prev * me_vy * nrm[i, D_ME]
                    xn2 += ts_prev * me_r * nrm[i, D_ME + 1]
                if c_vx >= 0:
                    xn0 += ts_prev * me_vx * nrm[i, c_vx]
                part[i, C_X + VX] = xn0
                part[i, C_X + VY] = xn1
                part[i, C_X + YAW_RATE] = xn2
                qi = q[i]
                bh0 += qi * part[i, C_B]
                bh1 += qi * part[i, C_B + 1]
                bh2 += qi * part[i, C_B + 2]
            if last:
                continue
            # ---- Algorithm 1, lines 2–5
            vx = part[i, C_X + VX]
            vy = part[i, C_X + VY]
            r = part[i, C_X + YAW_RATE]
            (f0, f1, f2, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, grx, gryf, gryr) = terms(
                vx, vy, r, delta, sd, cd, om_f, om_r, ts, p)
            l00 = part[i, C_LAM + L00]
            l01 = part[i, C_LAM + L01]
            l02 = part[i, C_LAM + L02]
            l11 = part[i, C_LAM + L11]
            l12 = part[i, C_LAM + L12]
            l22 = part[i, C_LAM + L22]
            # rows of d Λ (accelerometer rows of d)
            a0, a1, a2 = sym3_mv(l00, l01, l02, l11, l12, l22, dxx, dxyf, dxyr)
            b0, b1, b2 = sym3_mv(l00, l01, l02, l11, l12, l22, dyx, dyyf, dyyr)
            m0 = part[i, C_MU + W_CX]
            m1 = part[i, C_MU + W_CYF]
            m2 = part[i, C_MU + W_CYR]
            # gyro row of the conditioning measurement: ψ̇_k (d row zero, eq. (12)) or, with
            # the look-ahead, ψ̇_{k+1} = f_ψ̇ + g_ψ̇ w_k (eq. (9)); z2b is the gyro residual
            # of eq. (30) either way
            z2b = y2 - r - part[i, C_B + M_YAW_RATE]
            if look_k:
                dr0 = grx
                dr1 = gryf
                dr2 = gryr
                z2 = (y2n - f2 - part[i, C_B + M_YAW_RATE]) - (dr0 * m0 + dr1 * m1 + dr2 * m2)
            else:
                dr0 = dr1 = dr2 = 0.0
                z2 = 0.0 if look else z2b
            cc0, cc1, cc2 = sym3_mv(l00, l01, l02, l11, l12, l22, dr0, dr1, dr2)
            # d Λ dᵀ
            g00 = a0 * dxx + a1 * dxyf + a2 * dxyr
            g01 = a0 * dyx + a1 * dyyf + a2 * dyyr
            g11 = b0 * dyx + b1 * dyyf + b2 * dyyr
            # Λ̃_ē, eq. (35): c1 d Λ dᵀ + c2 (R + P); the gyro row couples only with the
            # look-ahead (without it e02 = e12 = 0 and the inverse is the 2 × 2 block and 1/err)
            e00 = c1 * g00 + c2 * (r00 + part[i, C_PB + PXX])
            e01 = c1 * g01 + c2 * (r01 + part[i, C_PB + PXY])
            e11 = c1 * g11 + c2 * (r11 + part[i, C_PB + PYY])
            e02 = c1 * (a0 * dr0 + a1 * dr1 + a2 * dr2)
            e12 = c1 * (b0 * dr0 + b1 * dr1 + b2 * dr2)
            err = c1 * (cc0 * dr0 + cc1 * dr1 + cc2 * dr2) + c2 * (
                rrr + part[i, C_PB + PRR] + me_r2)
            det = e00 * e11 - e01 * e01
            k00 = e11 * err - e12 * e12
            k01 = e02 * e12 - e01 * err
            k02 = e01 * e12 - e02 * e11
            det_all = e00 * k00 + e01 * k01 + e02 * k02
            inv_all = 1.0 / det_all
            i00 = k00 * inv_all
            i01 = k01 * inv_all
            i02 = k02 * inv_all
            i11 = (e00 * err - e02 * e02) * inv_all
            i12 = (e01 * e02 - e00 * e12) * inv_all
            i22 = det * inv_all
            # innovation z = ē − d μ̂ with ē = y − h − b (bias marginalised through P)
            z0 = y0 - ax - part[i, C_B + M_AX] - (dxx * m0 + dxyf * m1 + dxyr * m2)
            z1 = y1 - ay - part[i, C_B + M_AY] - (dyx * m0 + dyyf * m1 + dyyr * m2)
            v0, v1, v2 = sym3_mv(i00, i01, i02, i11, i12, i22, z0, z1, z2)
            maha = z0 * v0 + z1 * v1 + z2 * v2
            # weight, eq. (36): St(z; 0, Λ̃_ē, ν̃) up to a factor common to all particles
            lw = logw[i] - 0.5 * math.log(det_all) - half_dof_c * math.log(1.0 + maha * inv_dof)
            if not lw > -math.inf:      # NaN (indefinite scale) drops the particle
                lw = -math.inf
            logw[i] = lw
            top = max(top, lw)
            # Theorem 1, eq. (40)–(41): S_w dᵀ = c1 (d Λ)ᵀ
            mc0 = m0 + c1 * (a0 * v0 + b0 * v1 + cc0 * v2)
            mc1 = m1 + c1 * (a1 * v0 + b1 * v1 + cc1 * v2)
            mc2 = m2 + c1 * (a2 * v0 + b2 * v1 + cc2 * v2)
            # (d Λ)ᵀ Λ̃⁻¹ columns
            t00, t01, t02 = sym3_mv(i00, i01, i02, i11, i12, i22, a0, b0, cc0)
            t10, t11, t12 = sym3_mv(i00, i01, i02, i11, i12, i22, a1, b1, cc1)
            t20, t21, t22 = sym3_mv(i00, i01, i02, i11, i12, i22, a2, b2, cc2)
            c00, c10, c20, c11, c21, c22 = chol3(
                l00 - c1 * (t00 * a0 + t01 * b0 + t02 * cc0),
                l01 - c1 * (t00 * a1 + t01 * b1 + t02 * cc1),
                l02 - c1 * (t00 * a2 + t01 * b2 + t02 * cc2),
                l11 - c1 * (t10 * a1 + t11 * b1 + t12 * cc1),
                l12 - c1 * (t10 * a2 + t11 * b2 + t12 * cc2),
                l22 - c1 * (t20 * a2 + t21 * b2 + t22 * cc2))
            n0 = nrm[i, D_W]
            n1 = nrm[i, D_W + 1]
            n2 = nrm[i, D_W + 2]
            # χ²_ν*/ν* by the Wilson–Hilferty cube of a normal (module docstring); the draw is
            # μ* + L_S n √(ν*/χ²) with L_S = √((ν̃ + maha) c1/ν*) L
            wh = max(1.0 - wh_a + wh_b * nrm[i, D_CHI], 1e-3)
            sc = math.sqrt((dof + maha) * c_scale / (wh * wh * wh))
            w0 = min(max(mc0 + sc * c00 * n0, lo0), hi0)
            w1 = min(max(mc1 + sc * (c10 * n0 + c11 * n1), lo1), hi1)
            w2 = min(max(mc2 + sc * (c20 * n0 + c21 * n1 + c22 * n2), lo2), hi2)
            # line 18 without the model-error noise: x_{k+1} = f + g w_k (eq. (9))
            part[i, C_XN + VX] = f0 + ts * (dxx * w0 + dxyf * w1 + dxyr * w2)
            part[i, C_XN + VY] = f1 + ts * (dyx * w0 + dyyf * w1 + dyyr * w2)
            part[i, C_XN + YAW_RATE] = f2 + grx * w0 + gryf * w1 + gryr * w2
            # eq. (19) with z = w − μ̂_{k|k−1}, then the forgetting (20) of Λ (c_upd = 0 and
            # lam_f = 1 on inactive steps: statistics frozen)
            zw0 = w0 - m0
            zw1 = w1 - m1
            zw2 = w2 - m2
            part[i, C_LAM + L00] = lam_f * (l00 + c_upd * zw0 * zw0)
            part[i, C_LAM + L01] = lam_f * (l01 + c_upd * zw0 * zw1)
            part[i, C_LAM + L02] = lam_f * (l02 + c_upd * zw0 * zw2)
            part[i, C_LAM + L11] = lam_f * (l11 + c_upd * zw1 * zw1)
            part[i, C_LAM + L12] = lam_f * (l12 + c_upd * zw1 * zw2)
            part[i, C_LAM + L22] = lam_f * (l22 + c_upd * zw2 * zw2)
            mp0 = min(max(m0 + g_post * zw0, lo0), hi0)
            mp1 = min(max(m1 + g_post * zw1, lo1), hi1)
            mp2 = min(max(m2 + g_post * zw2, lo2), hi2)
            part[i, C_MU + W_CX] = mp0
            part[i, C_MU + W_CYF] = mp1
            part[i, C_MU + W_CYR] = mp2
            # for eq. (30): y − h − d μ̂_{k|k} − b_{k|k−1} and d Σ̂_{k|k} dᵀ with
            # d Λ_{k|k} dᵀ = d Λ dᵀ + c_upd (d z_w)(d z_w)ᵀ
            dm0 = mp0 - m0
            dm1 = mp1 - m1
            dm2 = mp2 - m2
            part[i, C_EB] = z0 - (dxx * dm0 + dxyf * dm1 + dxyr * dm2)
            part[i, C_EB + 1] = z1 - (dyx * dm0 + dyyf * dm1 + dyyr * dm2)
            if look_k:
                # eq. (30)'s gyro residual is that of the look-ahead row, taken before the draw
                # has pulled ψ̇_{k+1} towards the gyro (after it, the cloud's ψ̇ follows
                # gyro − b̂ and the residual no longer sees an error in b̂)
                part[i, C_EB + 2] = z2 - (dr0 * dm0 + dr1 * dm1 + dr2 * dm2)
                dzr = dr0 * zw0 + dr1 * zw1 + dr2 * zw2
                part[i, C_SB + PRR] = inv_c_post * (
                    cc0 * dr0 + cc1 * dr1 + cc2 * dr2 + c_upd * dzr * dzr) + me_r2
            else:
                part[i, C_EB + 2] = z2b
                part[i, C_SB + PRR] = 0.0
            dz0 = dxx * zw0 + dxyf * zw1 + dxyr * zw2
            dz1 = dyx * zw0 + dyyf * zw1 + dyyr * zw2
            part[i, C_SB + PXX] = inv_c_post * (g00 + c_upd * dz0 * dz0)
            part[i, C_SB + PXY] = inv_c_post * (g01 + c_upd * dz0 * dz1)
            part[i, C_SB + PYY] = inv_c_post * (g11 + c_upd * dz1 * dz1)
        if finish:
            b_hat[k - 1, 0] = bh0
            b_hat[k - 1, 1] = bh1
            b_hat[k - 1, 2] = bh2
        if last:
            break
        if act:
            gamma = g_post / lam_k    # (19a) then (20)
            nu = lam_k * nu_post      # (19c) then (20)
        # ---- lines 6–7 and 11–13 in one pass (moments about particle 0 for round-off)
        if top == -math.inf:
            for i in range(n_part):
                logw[i] = 0.0
            top = 0.0
        xr0 = part[0, C_X + VX]
        xr1 = part[0, C_X + VY]
        xr2 = part[0, C_X + YAW_RATE]
        mr0 = part[0, C_MU + W_CX]
        mr1 = part[0, C_MU + W_CYF]
        mr2 = part[0, C_MU + W_CYR]
        c_lam = inv_c_post / lam_f    # Λ_{k|k}/(ν_{k|k} − 4) from the stored λ Λ_{k|k}
        s = 0.0
        s2 = 0.0
        sx0 = sx1 = sx2 = 0.0
        sxx00 = sxx01 = sxx02 = sxx11 = sxx12 = sxx22 = 0.0
        sm0 = sm1 = sm2 = 0.0
        smm00 = smm01 = smm02 = smm11 = smm12 = smm22 = 0.0
        for i in range(n_part):
            e = math.exp(logw[i] - top)
            q[i] = e
            s += e
            s2 += e * e
            d0 = part[i, C_X + VX] - xr0
            d1 = part[i, C_X + VY] - xr1
            d2 = part[i, C_X + YAW_RATE] - xr2
            ed0 = e * d0
            ed1 = e * d1
            ed2 = e * d2
            sx0 += ed0
            sx1 += ed1
            sx2 += ed2
            sxx00 += ed0 * d0
            sxx01 += ed0 * d1
            sxx02 += ed0 * d2
            sxx11 += ed1 * d1
            sxx12 += ed1 * d2
            sxx22 += ed2 * d2
            d0 = part[i, C_MU + W_CX] - mr0
            d1 = part[i, C_MU + W_CYF] - mr1
            d2 = part[i, C_MU + W_CYR] - mr2
            ed0 = e * d0
            ed1 = e * d1
            ed2 = e * d2
            ec = e * c_lam
            sm0 += ed0
            sm1 += ed1
            sm2 += ed2
            smm00 += ed0 * d0 + ec * part[i, C_LAM + L00]
            smm01 += ed0 * d1 + ec * part[i, C_LAM + L01]
            smm02 += ed0 * d2 + ec * part[i, C_LAM + L02]
            smm11 += ed1 * d1 + ec * part[i, C_LAM + L11]
            smm12 += ed1 * d2 + ec * part[i, C_LAM + L12]
            smm22 += ed2 * d2 + ec * part[i, C_LAM + L22]
        inv_s = 1.0 / s
        neff = s * s / s2
        ess[k] = neff
        # eq. (42): weighted mean and covariance of x_k
        mx0 = sx0 * inv_s
        mx1 = sx1 * inv_s
        mx2 = sx2 * inv_s
        v00 = sxx00 * inv_s - mx0 * mx0
        v01 = sxx01 * inv_s - mx0 * mx1
        v02 = sxx02 * inv_s - mx0 * mx2
        v11 = sxx11 * inv_s - mx1 * mx1
        v12 = sxx12 * inv_s - mx1 * mx2
        v22 = sxx22 * inv_s - mx2 * mx2
        x_hat[k, VX] = xr0 + mx0
        x_hat[k, VY] = xr1 + mx1
        x_hat[k, YAW_RATE] = xr2 + mx2
        x_var[k, VX] = v00
        x_var[k, VY] = v11
        x_var[k, YAW_RATE] = v22
        # eq. (27a)–(27b) with the statistics S_{k|k}
        mw0 = sm0 * inv_s
        mw1 = sm1 * inv_s
        mw2 = sm2 * inv_s
        w_hat[k, W_CX] = mr0 + mw0
        w_hat[k, W_CYF] = mr1 + mw1
        w_hat[k, W_CYR] = mr2 + mw2
        w_cov[k, 0, 0] = smm00 * inv_s - mw0 * mw0
        w_cov[k, 0, 1] = w_cov[k, 1, 0] = smm01 * inv_s - mw0 * mw1
        w_cov[k, 0, 2] = w_cov[k, 2, 0] = smm02 * inv_s - mw0 * mw2
        w_cov[k, 1, 1] = smm11 * inv_s - mw1 * mw1
        w_cov[k, 1, 2] = w_cov[k, 2, 1] = smm12 * inv_s - mw1 * mw2
        w_cov[k, 2, 2] = smm22 * inv_s - mw2 * mw2
        # cloud covariance through ∂h/∂x for the bias filter of lines 14–20
        hx = accel_jacobian(x_hat[k, VX], x_hat[k, VY], x_hat[k, YAW_RATE], delta, sd, cd,
                            om_f, om_r, ts, p)
        x_unc[PXX], x_unc[PXY], x_unc[PYY], x_unc[PRR] = project_state_cov(
            hx, v00, v01, v02, v11, v12, v22)
        # ---- lines 8–10
        for i in range(n_part):
            q[i] *= inv_s
        if neff <= n_thr:
            systematic_resample(q, uniform(rng_state), idx)
            for i in range(n_part):
                j = idx[i]
                for c in range(N_COL):
                    spare[i, c] = part[j, c]
            part, spare = spare, part
            for i in range(n_part):
                q[i] = 1.0 / n_part
                logw[i] = -log_n
            n_resampled += 1
        else:
            shift = top + math.log(s)
            for i in range(n_part):
                logw[i] -= shift
        ts_prev = ts
    if n_resampled % 2 == 1:
        # the caller's array is the other buffer after an odd number of swaps
        spare[:, :] = part
    shared[0] = gamma
    shared[1] = nu
    return n_resampled
