"""The random stream of the Algorithm-1 kernel: xoshiro256** bits and ziggurat normals."""

import math

import numpy as np
from scipy import special, stats

from vestim.estimators.stiffness.draws import (
    ZIG_R,
    ZIG_V,
    fill_normals,
    seed_state,
    uniform,
    ziggurat_tables,
)

MASK = (1 << 64) - 1


def _xoshiro256ss(state: list[int], n: int) -> list[int]:
    """Plain-Python transcription of xoshiro256** 1.0 (Blackman & Vigna, reference C code)."""
    s = list(state)
    out = []
    for _ in range(n):
        x = (s[1] * 5) & MASK
        out.append((((x << 7) | (x >> 57)) & MASK) * 9 & MASK)
        t = (s[1] << 17) & MASK
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = ((s[3] << 45) | (s[3] >> 19)) & MASK
    return out


def test_bit_stream_is_xoshiro256starstar():
    """The compiled stream equals the reference algorithm word for word (uniform = top 53 bits / 2⁵³)."""
    state = np.array([0x0123456789ABCDEF, 0xFEDCBA9876543210, 0x0F1E2D3C4B5A6978, 0x1],
                     dtype=np.uint64)
    words = _xoshiro256ss([int(v) for v in state], 50)
    got = [uniform(state) for _ in range(50)]
    assert got == [(w >> 11) * 2.0**-53 for w in words]


def test_seed_state_is_reproducible_and_nonzero():
    a = seed_state(np.random.default_rng(5))
    b = seed_state(np.random.default_rng(5))
    assert a.dtype == np.uint64 and a.shape == (4,) and a.any()
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, seed_state(np.random.default_rng(6)))


def test_ziggurat_layers_have_equal_area():
    """Marsaglia & Tsang's construction: every layer i ≥ 1 has area x_i (f(x_{i−1}) − f(x_i)) = v,
    and the base layer r f(r) plus the tail ∫_r^∞ f = √(π/2) erfc(r/√2) is v too (f(x) =
    exp(−x²/2)); r and v to the 12 digits Marsaglia & Tsang give, hence 1e-9."""
    k, w, f = ziggurat_tables()
    x = w * 2.0**52
    areas = x[1:] * (f[:-1] - f[1:])
    np.testing.assert_allclose(areas, ZIG_V, rtol=1e-9)
    tail = math.sqrt(math.pi / 2) * special.erfc(ZIG_R / math.sqrt(2))
    assert math.isclose(ZIG_R * math.exp(-0.5 * ZIG_R**2) + tail, ZIG_V, rel_tol=1e-9)
    assert np.all(np.diff(x[1:]) > 0) and x[-1] == ZIG_R
    assert np.all(k[2:] < 2**52) and np.all(k[2:] > 0)


def test_normals_are_standard_normal():
    """2·10⁶ seeded draws: mean, variance, skewness and excess kurtosis within 5 standard errors
    of N(0, 1) (SE √(1/n), √(2/n), √(6/n), √(24/n)); Kolmogorov–Smirnov p > 0.01 (seeded, so
    deterministic); the tail beyond the ziggurat's r, where the slow path draws, within
    5 binomial standard errors of 2 Φ(−r)."""
    n = 2_000_000
    z = np.empty(n)
    fill_normals(seed_state(np.random.default_rng(1)), z)
    assert abs(z.mean()) < 5 * math.sqrt(1 / n)
    assert abs(z.var() - 1) < 5 * math.sqrt(2 / n)
    assert abs(stats.skew(z)) < 5 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24 / n)
    assert stats.kstest(z, "norm").pvalue > 0.01
    p_tail = 2 * stats.norm.sf(ZIG_R)
    assert abs(np.mean(np.abs(z) > ZIG_R) - p_tail) < 5 * math.sqrt(p_tail / n)
    assert abs(np.mean(z > 0) - 0.5) < 5 * math.sqrt(0.25 / n)


def test_fill_advances_the_state_and_takes_any_shape():
    """A (3, 4) block draws the same numbers as 12 in a row; the next fill continues the stream."""
    s1 = seed_state(np.random.default_rng(2))
    s2 = s1.copy()
    a = np.empty((3, 4))
    fill_normals(s1, a)
    b = np.empty(12)
    fill_normals(s2, b)
    np.testing.assert_array_equal(a.ravel(), b)
    np.testing.assert_array_equal(s1, s2)
    c = np.empty(12)
    fill_normals(s1, c)
    assert not np.array_equal(b, c)
