"""Properties of the shared figure helpers: the shared y range holds every finite value with
at most 5 % padding, and the scatter reduction keeps at most max_points samples in time
order, including the sample of largest magnitude (the peak friction use)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from vestim.constants import CORNERS
from vestim.report.data import peak_points
from vestim.report.style import CORNER_COLORS, GRID, axis_label, rgba, shared_range

finite = st.floats(-1e6, 1e6, allow_nan=False)
values = arrays(np.float64, st.integers(1, 300),
                elements=st.one_of(finite, st.just(np.nan), st.just(np.inf)))


@given(st.lists(values, min_size=1, max_size=4))
@settings(max_examples=200, deadline=None)
def test_shared_range_holds_every_finite_value(parts: list[np.ndarray]) -> None:
    rng = shared_range(parts)
    data = np.concatenate(parts)
    data = data[np.isfinite(data)]
    if data.size == 0:
        assert rng is None
        return
    assert rng is not None
    lo, hi = rng
    assert lo <= data.min() and hi >= data.max() and lo < hi
    span = data.max() - data.min()
    if span > 0:
        assert data.min() - lo <= 0.05 * span * (1 + 1e-9)
        assert hi - data.max() <= 0.05 * span * (1 + 1e-9)


@given(st.integers(1, 5000), st.integers(2, 400), st.integers(0, 2**32 - 1))
@settings(max_examples=100, deadline=None)
def test_peak_points_keeps_the_peak(n: int, max_points: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    x[rng.random(n) < 0.05] = np.nan
    idx = peak_points(x, y, max_points)
    assert idx.size <= max_points
    assert np.all(np.diff(idx) > 0)  # time order, no sample twice
    assert np.all(np.isfinite(x[idx]) & np.isfinite(y[idx]))
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.any():
        r = np.where(ok, np.hypot(np.nan_to_num(x), np.nan_to_num(y)), -1.0)
        assert int(np.argmax(r)) in set(idx.tolist())
    if n <= max_points:
        assert idx.size == int(ok.sum())


def test_style_constants() -> None:
    """Four distinct corner colours; the grid puts the front row on top, left on the left."""
    assert set(CORNER_COLORS) == set(CORNERS) == set(GRID)
    assert len(set(CORNER_COLORS.values())) == 4
    assert GRID == {"fl": (0, 0), "fr": (0, 1), "rl": (1, 0), "rr": (1, 1)}
    assert axis_label("fx", "N") == "F_x [N]" and axis_label("slip_ratio", "-") == "slip ratio [-]"
    assert rgba("#0072B2", 0.5) == "rgba(0,114,178,0.5)"
