"""``one_of``, the membership test of a batch's columns in a few codes (kinds, roles,
functions) that the columnar paths use instead of ``np.isin``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.modbus.columnar import one_of


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(-2, 300), max_size=60), st.frozensets(st.integers(-2, 300), max_size=24))
def test_one_of_is_isin(values: list[int], members: frozenset[int]) -> None:
    """``one_of`` (equalities or'ed for a few members) says what ``np.isin`` says, for any number."""
    column = np.array(values, np.int64)
    assert one_of(column, members).tolist() == np.isin(column, list(members)).tolist()
