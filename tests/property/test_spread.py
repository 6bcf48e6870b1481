"""Hypothesis: :func:`decoders.modbus.columnar.spread` is the repeat it stands for."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from decoders.runs import spread, within_runs


@given(st.lists(st.tuples(st.integers(-70_000, 70_000), st.integers(0, 40)), max_size=30), st.integers(1, 8),
       st.sampled_from([np.int32, np.int64]))
def test_spread_is_each_base_plus_its_items_places(runs: list[tuple[int, int]], step: int,
                                                  dtype: type[np.signedinteger]) -> None:
    bases = np.array([base for base, _ in runs], np.int64)
    counts = np.array([count for _, count in runs], np.int64)
    got = spread(bases, counts, step, dtype)
    assert got.dtype == dtype
    assert got.tolist() == (np.repeat(bases, counts) + step * within_runs(counts)).tolist()
    assert got.tolist() == [base + step * place for base, count in runs for place in range(count)]
