"""Hypothesis: a :class:`Block` writes what ``json`` reads back exactly, in rows of one width."""

from __future__ import annotations

import json
import os
from decimal import Decimal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.encoding.blocks import Block, times_matrix

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))
INT64 = st.integers(-(2**63), 2**63 - 1)
NONE = -1


@settings(max_examples=max(300, EXAMPLES), deadline=None)
@given(
    st.lists(st.one_of(INT64, st.integers(-20, 20), st.just(NONE)), min_size=1, max_size=40),
    st.integers(0, 12),
    st.lists(st.integers(0, 3), min_size=40, max_size=40),
)
def test_rows_read_back_as_the_exact_numbers(values: list[int], places: int, keys: list[int]) -> None:
    column = np.array(values, np.int64)
    choices = [b"[]", b'["gap_1_5"]', b'"x"', b"null"]
    picked = np.array(keys[: len(values)], np.int64)
    rows = (
        Block(len(values))
        .text(b'{"integer":').integers(column)
        .text(b',"or_null":').integers(column, NONE)
        .text(b',"decimal":').decimals(column, places, NONE)
        .text(b',"choice":').choice(picked, choices)
        .text(b"}")
        .pieces()
    )  # fmt: skip
    assert len({len(row) for row in rows}) == 1 and list(rows.sizes) == [len(row) for row in rows]
    for row, value, key in zip(rows, values, picked.tolist(), strict=True):
        record = json.loads(row, parse_float=Decimal)
        assert record["integer"] == value
        assert record["or_null"] == (None if value == NONE else value)
        expected = None if value == NONE else Decimal(value).scaleb(-places)
        assert record["decimal"] == expected
        assert json.dumps(record["choice"], separators=(",", ":")).encode() == choices[key]
        if places and value != NONE:  # every fraction digit written, as the nanoseconds' exact decimal
            assert len(row.split(b'"decimal":')[1].split(b",")[0].strip().split(b".")[1]) == places


def test_a_column_without_the_none_value_takes_no_room_for_null() -> None:
    rows = Block(2).text(b"[").integers(np.array([1, 2]), NONE).text(b"]").pieces()
    assert list(rows) == [b"[1]", b"[2]"]


def test_a_row_ending_in_a_zero_byte_is_refused() -> None:
    """``tolist`` of a bytes view drops trailing zeros: such a row would lose bytes silently."""
    with pytest.raises(ValueError, match="zero byte"):
        Block(2).text(b"{").text(bytes(3)).pieces()


epoch_ns = st.integers(10**18, (1 << 63) - 1)  # 19 digits that fit int64


@given(st.lists(st.tuples(epoch_ns, epoch_ns), max_size=20))
def test_times_matrix_spells_the_four_times(times: list[tuple[int, int]]) -> None:
    t_start = np.array([t for t, _ in times], np.int64)
    t_end = np.array([t for _, t in times], np.int64)
    block = times_matrix(t_start, t_end)
    if not times:
        assert block is None
        return
    assert block is not None
    for text, (start, end) in zip(block.view(f"S{block.shape[1]}").ravel().tolist(), times, strict=True):
        fields = json.loads(b"{" + text[1:] + b"}", parse_float=Decimal)
        assert fields == {
            "t": Decimal(start).scaleb(-9),
            "t_end": Decimal(end).scaleb(-9),
            "t_ns": start,
            "t_end_ns": end,
        }


@given(st.lists(st.integers(0, 10**18 - 1), min_size=1, max_size=5))
def test_times_matrix_leaves_other_times_to_the_fields(times: list[int]) -> None:
    column = np.array(times, np.int64)
    assert times_matrix(column, column) is None
