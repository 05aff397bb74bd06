"""Output framing: column groups of consecutive chunks into one frame (vestim.io.frames)."""

import numpy as np
import pytest

from vestim.io.frames import frame_from_chunks


def test_chunks_fill_their_rows_of_one_frame() -> None:
    """Two chunks of a (n,) and an (n, 2) group: each value lands in its row and column
    (the block is filled as its transpose, so a transposed copy would swap them)."""
    a = np.arange(6.0).reshape(3, 2)
    b = 10.0 + np.arange(4.0).reshape(2, 2)
    frame = frame_from_chunks([[(["t"], np.array([0.0, 1.0, 2.0])), (["x", "y"], a)],
                               [(["t"], np.array([3.0, 4.0])), (["x", "y"], b)]], 5)
    assert list(frame.columns) == ["t", "x", "y"]
    assert frame.to_numpy().tolist() == [[0, 0, 1], [1, 2, 3], [2, 4, 5], [3, 10, 11],
                                         [4, 12, 13]]


def test_a_chunk_with_other_columns_is_refused() -> None:
    """A later chunk without one of the first chunk's columns would leave its rows unset:
    the error names both column lists."""
    with pytest.raises(ValueError, match=r"row 1 has the columns \['t'\], not the first"):
        frame_from_chunks([[(["t"], np.zeros(1)), (["x"], np.zeros(1))],
                           [(["t"], np.zeros(1))]], 2)
