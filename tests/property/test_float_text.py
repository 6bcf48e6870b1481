"""Hypothesis: floats spelt through Arrow are spelt as ``repr`` spells them.

One test body runs over the Arrow path (``float_texts``, with ``ARROW_FROM`` lowered so
that short columns take it too) and over short columns' ``repr`` path; both are held to each
number's own ``repr``.
"""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.encoding import float_text
from sniffer.encoding.float_text import FIXED_HIGH, FIXED_LOW, float_texts

#: Seconds from nanoseconds (times and latencies), and any float at all.
NANOSECONDS = st.integers(-(2**63), 2**63 - 1).map(lambda ns: ns / 1e9)
EDGES = st.sampled_from([0.0, -0.0, 2.0, -7.0, FIXED_LOW, FIXED_HIGH, np.nextafter(FIXED_LOW, 0),
                         np.nextafter(FIXED_HIGH, 0), 12345000000.0, 999999900000.0001, 1e21, 1e-7])
NUMBERS = st.lists(st.one_of(NANOSECONDS, st.floats(), EDGES), max_size=60)


@pytest.mark.parametrize("arrow_from", [1, float_text.ARROW_FROM], ids=["arrow", "short"])
@settings(max_examples=300, deadline=None)
@given(numbers=NUMBERS)
def test_floats_are_spelt_as_repr_spells_them(numbers: list[float], arrow_from: int) -> None:
    column = np.array(numbers, np.float64)
    with mock.patch.object(float_text, "ARROW_FROM", arrow_from):
        texts = float_texts(column)
    assert list(texts) == [repr(float(number)).encode() for number in numbers]
    assert texts.sizes.tolist() == [len(repr(float(number))) for number in numbers]


def test_a_capture_day_of_times_goes_through_arrow() -> None:
    """Times of a day's frames (long columns: Arrow's path without lowering anything)."""
    rng = np.random.default_rng(1)
    times = (1_700_000_000_000_000_000 + np.cumsum(rng.integers(1, 50_000_000, 5_000))) / 1e9
    with mock.patch.object(float_text, "number_texts", side_effect=AssertionError("repr path taken")):
        texts = float_texts(times)
    assert list(texts) == [repr(t).encode() for t in times.tolist()]
