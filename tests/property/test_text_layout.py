"""Hypothesis: lines laid out field by field (:mod:`decoders.modbus.text_layout`) say what
``%`` and ``bytes.hex`` say of each row, whatever the widths of the rows' numbers and texts."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.modbus.text_layout import bits, chosen, decimal, hex_words, lines, present, upper_hex

NUMBERS = st.lists(st.integers(0, 2**40), max_size=40)
WORDS = st.lists(st.integers(0, 0xFFFF), max_size=40)


@settings(max_examples=200, deadline=None)
@given(numbers=NUMBERS, words=WORDS)
def test_numbers_are_spelt_as_percent_spells_them(numbers: list[int], words: list[int]) -> None:
    count = min(len(numbers), len(words))
    numbers, words = numbers[:count], words[:count]
    laid = lines(["n=", decimal(np.array(numbers, np.int64)), " (0x", upper_hex(np.array(words, np.int64), 4), ")"],
                 count)
    assert laid == [f"n={n} (0x{w:04X})" for n, w in zip(numbers, words, strict=True)]


@settings(max_examples=200, deadline=None)
@given(rows=st.lists(st.tuples(st.integers(0, 2), st.booleans(), st.integers(0, 999)), max_size=30))
def test_chosen_and_present_fields_show_only_where_they_are(rows: list[tuple[int, bool, int]]) -> None:
    table = ["ON", "OFF", ""]
    index = np.array([row[0] for row in rows], np.int64)
    shown = np.array([row[1] for row in rows], np.bool_)
    number = np.array([row[2] for row in rows], np.int64)
    laid = lines([chosen(index, table), present(shown, ".."), present(shown, decimal(number)), "|"], len(rows))
    assert laid == [table[i] + (f"..{n}" if s else "") + "|" for i, s, n in rows]


@settings(max_examples=200, deadline=None)
@given(data=st.binary(min_size=1, max_size=64), picks=st.lists(st.tuples(st.integers(0, 63), st.integers(1, 300)),
                                                                min_size=1, max_size=20))
def test_bits_are_the_first_shown_bits_then_an_ellipsis(data: bytes, picks: list[tuple[int, int]]) -> None:
    starts = np.array([start % len(data) for start, _ in picks], np.int64)
    counts = np.array([min(count, 8 * (len(data) - start)) for start, (_, count) in zip(starts.tolist(), picks,
                                                                                         strict=True)], np.int64)
    expected = []
    for start, count in zip(starts.tolist(), counts.tolist(), strict=True):
        every = "".join("1" if data[start + n // 8] >> (n % 8) & 1 else "0" for n in range(count))
        expected.append(every[:32] + ("…" if count > 32 else ""))
    assert lines([bits(data, starts, counts, 32)], len(picks)) == expected


@settings(max_examples=200, deadline=None)
@given(data=st.binary(min_size=2, max_size=40), picks=st.lists(st.tuples(st.integers(0, 39), st.integers(0, 8)),
                                                                min_size=1, max_size=20))
def test_hex_words_are_spelt_as_bytes_hex_spells_them(data: bytes, picks: list[tuple[int, int]]) -> None:
    starts = np.array([start % (len(data) - 1) for start, _ in picks], np.int64)
    counts = np.array([min(count, (len(data) - start) // 2) for start, (_, count) in zip(starts.tolist(), picks,
                                                                                          strict=True)], np.int64)
    expected = [data[start : start + 2 * count].hex(" ", 2).upper()
                for start, count in zip(starts.tolist(), counts.tolist(), strict=True)]
    assert lines(["[", hex_words(data, starts, counts), "]"], len(picks)) == [f"[{text}]" for text in expected]


def test_no_rows_lay_out_no_lines_and_negative_numbers_are_refused() -> None:
    empty = np.zeros(0, np.int64)
    assert lines(["x", decimal(empty), bits(b"\x01", empty, empty, 32), hex_words(b"\x01\x02", empty, empty)], 0) == []
    with pytest.raises(ValueError, match="negative"):
        decimal(np.array([3, -1]))
