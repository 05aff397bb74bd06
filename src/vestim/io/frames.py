"""Output framing: named column groups of estimates into a name → array mapping or one
DataFrame (the estimated channels of docs/format.md, float64, ``t`` first by convention).

A stage's result is a list of :data:`ColumnGroup`: spec column names with their values,
one (n,) array for one name or an (n, k) array for k names (the four corners of a
quantity), so that a group is copied into the frame in one strided copy.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

__all__ = ["ColumnGroup", "columns_from_groups", "frame_from_chunks"]

ColumnGroup = tuple[list[str], np.ndarray]
"""Spec column names and their values: (n,) for one name, (n, k) for k names."""


def columns_from_groups(groups: list[ColumnGroup]) -> dict[str, np.ndarray]:
    """Flatten column groups into a name → (n,) mapping (views, no copies)."""
    cols: dict[str, np.ndarray] = {}
    for group_names, values in groups:
        if values.ndim == 1:
            cols[group_names[0]] = values
        else:
            for i, name in enumerate(group_names):
                cols[name] = values[:, i]
    return cols


def frame_from_chunks(chunks: Iterable[list[ColumnGroup]], n: int) -> pd.DataFrame:
    """One float64 DataFrame from consecutive chunks of column groups (n samples in all), each
    chunk with the same groups in the same order (the first fixes the columns).

    The block is filled as its transpose (pandas stores a float block as (columns, samples)),
    so each group is one strided copy and the frame is not copied again.

    Raises:
        ValueError: a chunk's columns are not the first chunk's.
    """
    names: list[str] = []
    block = np.empty((0, n))
    start = 0
    for groups in chunks:
        chunk_names = [name for g, _ in groups for name in g]
        if not names:
            names = chunk_names
            block = np.empty((len(names), n))
        elif chunk_names != names:
            raise ValueError(f"frame_from_chunks: a chunk at row {start} has the columns "
                             f"{chunk_names}, not the first chunk's {names}")
        stop = start + groups[0][1].shape[0]
        j = 0
        for group_names, values in groups:
            block[j:j + len(group_names), start:stop] = values.T if values.ndim == 2 else values
            j += len(group_names)
        start = stop
    return pd.DataFrame(block.T, columns=names, copy=False)
