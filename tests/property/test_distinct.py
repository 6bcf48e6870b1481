"""Hypothesis: :func:`decoders.distinct.distinct` is ``np.unique`` of the values alone."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from decoders.distinct import COUNTED_SPAN, FEW, distinct

DTYPES = [np.int8, np.uint8, np.int16, np.uint16, np.int32, np.int64, np.uint64, np.float64]


@given(st.sampled_from(DTYPES), st.integers(0, 3 * FEW), st.sampled_from([3, 300, COUNTED_SPAN, 1 << 40]),
       st.integers(-(1 << 20), 1 << 20), st.randoms())
def test_distinct_is_what_unique_says(dtype: type, size: int, span: int, low: int, rng: object) -> None:
    info = np.iinfo(dtype) if np.issubdtype(dtype, np.integer) else None
    generator = np.random.default_rng(rng.randrange(1 << 30))  # type: ignore[attr-defined]
    values = generator.integers(0, span, size, dtype=np.int64) + low
    if info is not None:
        values = np.clip(values, info.min, info.max)
    column = values.astype(dtype)
    got = distinct(column)
    assert got.dtype == column.dtype
    assert got.tolist() == np.unique(column).tolist()


def test_a_list_and_nothing() -> None:
    assert distinct([3, 1, 3]).tolist() == [1, 3]
    assert distinct(np.zeros(0, np.int16)).dtype == np.int16
