"""Output framing: named column groups of estimates into a name → array mapping or one
DataFrame (the estimated channels of docs/format.md, float64, ``t`` first by convention).

A stage's result is a list of :data:`ColumnGroup`: spec column names with their values,
one (n,) array for one name or an (n, k) array for k names (the four corners of a
quantity), so that a group is copied into the frame in one strided copy.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

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


def frame_from_chunks(chunks: Iterable[list[ColumnGroup]], n: int,
                      names: Sequence[str] = ()) -> pd.DataFrame:
    """One float64 DataFrame from consecutive chunks of column groups (n samples in all).

    The first chunk fixes the columns, unless ``names`` does (the columns of the earlier
    pieces of a log estimated piece by piece); a later chunk fills its rows of the block, and
    a column it lacks is NaN there. The block is filled as its transpose (pandas stores a
    float block as (columns, samples)), so each group is one strided copy and the frame
    is not copied again.
    """
    names = list(names)
    rows: dict[str, int] = {name: j for j, name in enumerate(names)}
    block = np.empty((len(names), n))
    start = 0
    for groups in chunks:
        if not names:
            names = [name for g, _ in groups for name in g]
            rows = {name: j for j, name in enumerate(names)}
            block = np.empty((len(names), n))
        stop = start + groups[0][1].shape[0]
        filled = np.zeros(len(names), dtype=bool)
        for group_names, values in groups:
            j = rows.get(group_names[0])
            if j is None:  # a channel the first chunk did not have (method-dependent)
                continue
            block[j:j + len(group_names), start:stop] = values.T if values.ndim == 2 else values
            filled[j:j + len(group_names)] = True
        block[~filled, start:stop] = np.nan
        start = stop
    return pd.DataFrame(block.T, columns=names, copy=False)
