"""Step-invariant (zero-order-hold) discretisation of the corner velocity models, in closed form.

000 Sec. III-B and 003 Appendix discretise the LuGre corner model by step
invariance: with the input held over a sample interval T,

    A_k = e^{A T},   B_k = ∫_0^T e^{A τ} B dτ.

``scipy.linalg.expm`` costs ~9 µs per call, far too slow per sample and corner,
so both models used here are discretised in closed form:

* the three-state Kalman model of 000 eq. (19) / 003 eq. (3)–(4)
  (:func:`kf_transition`), whose state matrix is triangular up to a permutation;
* any 2 × 2 matrix (:func:`expm2_phi`), for the closed-loop LPV observers of 001
  eq. (24), (38) and 004 eq. (10)–(14): the Cayley–Hamilton form of e^{Mh}.

Both are checked against ``scipy.linalg.expm`` and ``scipy.integrate.quad_vec`` in
``tests/estimators/velocity/test_corner_discrete.py``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

_SERIES_BELOW = 0.25
"""x = aT below which the φ-functions are summed as series (their closed forms cancel)."""
_SERIES_TERMS = 12
"""Terms of those series: x^12/14! < 7e-19 for x < 0.25, below double precision."""


def _coefficients() -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    fact = [float(math.factorial(n + 2)) for n in range(_SERIES_TERMS)]
    p2 = tuple((n + 1) / fact[n] * (-1) ** n for n in range(_SERIES_TERMS))
    q1 = tuple(1.0 / fact[n] * (-1) ** n for n in range(_SERIES_TERMS))
    q2 = tuple((n + 1) / (fact[n] * (n + 3)) * (-1) ** n for n in range(_SERIES_TERMS))
    return p2, q1, q2


_C_P2, _C_Q1, _C_Q2 = _coefficients()


@njit(**_JIT)
def _horner(c: tuple[float, ...], x: float) -> float:
    v = 0.0
    for i in range(len(c) - 1, -1, -1):
        v = v * x + c[i]
    return v


@njit(**_JIT)
def decay_functions(x: float) -> tuple[float, float, float, float]:
    """Entire functions of x = aT ≥ 0 used by :func:`kf_transition`.

    p1 = (1 − e^{−x})/x,  p2 = (p1 − e^{−x})/x,  q1 = (1 − p1)/x,  q2 = (q1 − p2)/x,
    each extended continuously to x = 0 (1, 1/2, 1/2, 1/6). Below x = 0.25 they are
    summed as power series (Horner), p2 = Σ (−x)^n (n+1)/(n+2)!, q1 = Σ (−x)^n/(n+2)!,
    q2 = Σ (−x)^n (n+1)/((n+2)!(n+3)), because the closed forms lose digits to
    cancellation there.
    """
    em1 = math.expm1(-x)
    if x < _SERIES_BELOW:
        p1 = -em1 / x if x > 0.0 else 1.0
        return p1, _horner(_C_P2, x), _horner(_C_Q1, x), _horner(_C_Q2, x)
    ix = 1.0 / x  # one division instead of four in a dependent chain
    p1 = -em1 * ix
    p2 = (p1 - (1.0 + em1)) * ix
    q1 = (1.0 - p1) * ix
    q2 = (q1 - p2) * ix
    return p1, p2, q1, q2


@njit(**_JIT)
def kf_transition(a: float, b: float, h: float, Ak: np.ndarray, Bk: np.ndarray) -> None:
    """Exact A_k = e^{A h} and B_k = ∫_0^h e^{A τ} B dτ of the Kalman corner model, in place.

    Continuous model (000 eq. (19) with M⁻¹ applied; 003 eq. (3)–(4)), state
    [z̄_x, v_rx, ż̄_x]::

        A = [[−a, 1, 0], [0, 0, 0], [−b, 0, −a]],   B = [0, 1, 1]ᵀ,
        a = κ_x R|ω| (1/s),  b = κ_x R d|ω|/dt (1/s²).

    v_rx is constant over the step, z̄ relaxes toward v_rx/a and the third row is
    a first-order lag driven by z̄, so, with E = e^{−ah} and the functions of
    :func:`decay_functions` at x = ah::

        A_k = [[E, h p1, 0], [0, 1, 0], [−b h E, −b h² p2, E]]
        B_k = [h² q1, h, h p1 − b h³ q2]ᵀ.

    Args:
        a: decay rate κR|ω| ≥ 0, 1/s (held over the step).
        b: its rate of change κR d|ω|/dt, 1/s² (held over the step).
        h: step length, s.
        Ak: (3, 3) output. Bk: (3,) output.
    """
    e, a01, a20, a21, b0, b1, b2 = kf_transition_entries(a, b, h)
    fill_transition(e, a01, a20, a21, b0, b1, b2, Ak, Bk)


@njit(**_JIT)
def fill_transition(e: float, a01: float, a20: float, a21: float, b0: float, b1: float,
                    b2: float, Ak: np.ndarray, Bk: np.ndarray) -> None:
    """A_k (3, 3) and B_k (3,) of :func:`kf_transition` from the entries that
    :func:`kf_transition_entries` returns (the others are 0 or 1)."""
    Ak[0, 0] = e
    Ak[0, 1] = a01
    Ak[0, 2] = 0.0
    Ak[1, 0] = 0.0
    Ak[1, 1] = 1.0
    Ak[1, 2] = 0.0
    Ak[2, 0] = a20
    Ak[2, 1] = a21
    Ak[2, 2] = e
    Bk[0] = b0
    Bk[1] = b1
    Bk[2] = b2


@njit(**_JIT)
def kf_transition_entries(a: float, b: float, h: float
                          ) -> tuple[float, float, float, float, float, float, float]:
    """The entries of :func:`kf_transition`'s A_k and B_k that are not 0 or 1, as floats
    (a kernel that keeps them in scalars saves the arrays' reference counting per step):
    (E = A_k[0, 0] = A_k[2, 2], A_k[0, 1] = h p1, A_k[2, 0] = −b h E, A_k[2, 1] = −b h² p2,
    B_k[0] = h² q1, B_k[1] = h, B_k[2] = h p1 − b h³ q2); a in 1/s, b in 1/s², h in s.
    """
    x = a * h
    e = math.exp(-x)
    p1, p2, q1, q2 = decay_functions(x)
    return e, h * p1, -b * h * e, -b * h * h * p2, h * h * q1, h, h * p1 - b * h * h * h * q2


@njit(**_JIT)
def _cosh_sinhc(d: float, h: float) -> tuple[float, float]:
    """For N² = d·I: (cosh(√d h) − 1, sinh(√d h)/√d, with the trigonometric forms for d < 0).

    Returns (c − 1, s) with c − 1 computed without cancellation (−2 sin²(·/2)
    or 2 sinh²(·/2)); for |d| h² < 1e-3 a series (error < 1e-19 relative).
    """
    y = d * h * h
    if abs(y) < 1e-3:
        cm1 = h * h * d * (0.5 + y / 24.0 + y * y / 720.0)
        s = h * (1.0 + y / 6.0 + y * y / 120.0 + y * y * y / 5040.0)
        return cm1, s
    if d > 0.0:
        q = math.sqrt(d)
        sh = math.sinh(0.5 * q * h)
        # sinh(qh) = 2 sinh(qh/2) cosh(qh/2), cosh = √(1 + sinh²): one transcendental call
        return 2.0 * sh * sh, 2.0 * sh * math.sqrt(1.0 + sh * sh) / q
    q = math.sqrt(-d)
    sn = math.sin(0.5 * q * h)
    return -2.0 * sn * sn, 2.0 * sn * math.cos(0.5 * q * h) / q


@njit(**_JIT)
def expm2_phi(m00: float, m01: float, m10: float, m11: float,
              h: float) -> tuple[float, float, float, float, float, float, float, float]:
    """e^{Mh} − I and Φ = ∫_0^h e^{Mτ} dτ of a 2 × 2 matrix M, in closed form.

    Cayley–Hamilton: with s = tr M/2 and N = M − sI (so N² = d I, d = s² − det M),
    e^{Mh} = e^{sh} (cosh(√d h) I + sinh(√d h)/√d N). The difference e^{Mh} − I is
    assembled from expm1 and the half-angle form of cosh − 1 so it keeps full
    relative precision for small ‖M‖h, and Φ = M⁻¹(e^{Mh} − I), which needs
    det M ≠ 0 (true for the LPV observers with L2 > 0: det = L2(σ0 + σ2κR|ω|)).
    For det M = 0 the returned Φ is NaN.

    Returns:
        (D00, D01, D10, D11, Φ00, Φ01, Φ10, Φ11) with D = e^{Mh} − I.
    """
    s = 0.5 * (m00 + m11)
    det = m00 * m11 - m01 * m10
    d = s * s - det
    cm1, sc = _cosh_sinhc(d, h)
    em1 = math.expm1(s * h)
    es = 1.0 + em1
    diag = em1 * (1.0 + cm1) + cm1  # e^{sh} c − 1
    n00 = m00 - s
    n11 = m11 - s
    D00 = diag + es * sc * n00
    D01 = es * sc * m01
    D10 = es * sc * m10
    D11 = diag + es * sc * n11
    if det == 0.0:
        nan = math.nan
        return D00, D01, D10, D11, nan, nan, nan, nan
    i00 = m11 / det
    i01 = -m01 / det
    i10 = -m10 / det
    i11 = m00 / det
    P00 = i00 * D00 + i01 * D10
    P01 = i00 * D01 + i01 * D11
    P10 = i10 * D00 + i11 * D10
    P11 = i10 * D01 + i11 * D11
    return D00, D01, D10, D11, P00, P01, P10, P11


def kf_transition_matrices(a: float, b: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """NumPy convenience wrapper of :func:`kf_transition`: returns (A_k (3, 3), B_k (3,))."""
    Ak = np.empty((3, 3))
    Bk = np.empty(3)
    kf_transition(float(a), float(b), float(h), Ak, Bk)
    return Ak, Bk


def expm2(m: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """NumPy convenience wrapper of :func:`expm2_phi`: returns (e^{Mh} (2, 2), Φ (2, 2)).

    e^{Mh} is evaluated as e^{sh}(c I + sinhc·N) (the Cayley–Hamilton form of
    :func:`expm2_phi`), not as I + (e^{Mh} − I): where e^{Mh} ≪ 1 (M = −1000 I, h = 0.0195:
    e^{−19.5} ≈ 3e-9) the sum with I keeps only ε of absolute precision, 1e-8 relative.
    The kernels use e^{Mh} − I and Φ, whose precision this does not concern."""
    m00, m01, m10, m11 = float(m[0, 0]), float(m[0, 1]), float(m[1, 0]), float(m[1, 1])
    r = expm2_phi(m00, m01, m10, m11, float(h))
    s = 0.5 * (m00 + m11)
    cm1, sc = _cosh_sinhc(s * s - (m00 * m11 - m01 * m10), float(h))
    es = math.exp(s * h)
    e = es * np.array([[1.0 + cm1 + sc * (m00 - s), sc * m01],
                       [sc * m10, 1.0 + cm1 + sc * (m11 - s)]])
    return e, np.array([[r[4], r[5]], [r[6], r[7]]])
