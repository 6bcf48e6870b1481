"""Hypothesis: the parts of :func:`decoders.modbus.alike.alike` against the plain Python they
stand for: spans compared 8 bytes at a time are equal where their slices are, and each row's
group first is the first row with its key."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.modbus.alike import _group_firsts, _same_bytes


@settings(max_examples=300, deadline=None)
@given(data=st.binary(min_size=1, max_size=80),
       spans=st.lists(st.tuples(st.integers(0, 79), st.integers(0, 79), st.integers(0, 40)), max_size=30),
       copies=st.lists(st.tuples(st.integers(0, 29), st.sampled_from([0, -1, 7, 8, -8, -9]) | st.integers(0, 39)
                                 | st.none()), max_size=10))
def test_spans_compared_by_words_are_same_where_their_slices_are(
        data: bytes, spans: list[tuple[int, int, int]], copies: list[tuple[int, int | None]]) -> None:
    """Spans of every start and length (the last word reading past the data); ``copies``: some
    spans' bytes copied from their other span, then one byte of them changed (``None``: none;
    negative: from the end), so that spans differ in their first byte, their last, either side
    of a word's edge, or any between."""
    buffer = bytearray(data)
    rows = []
    for first, second, most in spans:
        one, other = first % len(buffer), second % len(buffer)
        rows.append((one, other, min(most, len(buffer) - one, len(buffer) - other)))
    for span, changed in copies if rows else []:
        one, other, length = rows[span % len(rows)]
        buffer[one : one + length] = buffer[other : other + length]
        if changed is not None and length:
            buffer[one + changed % length] ^= 0x5A
    data = bytes(buffer)
    starts, others, lengths = (np.array([row[place] for row in rows], np.int64) for place in range(3))
    expected = [data[one : one + length] == data[other : other + length] for one, other, length in rows]
    assert _same_bytes(data, starts, others, lengths).tolist() == expected
    assert _same_bytes(data, starts, starts, lengths).all()


def test_spans_differing_in_any_one_byte_differ_at_every_length_and_offset() -> None:
    """Every length up to three words, every byte changed in turn, at starts of every
    alignment, the second span ending at the data's end: only the unchanged are the same."""
    for length in range(25):
        for shift in range(8):
            base = bytes((7 * n + 3) % 256 for n in range(shift + length)) + b"\xff" * 5  # unlike the padding
            data = base + base[shift : shift + length]  # the copy ends the data
            starts, others = np.array([shift], np.int64), np.array([len(base)], np.int64)
            assert _same_bytes(data, starts, others, np.array([length], np.int64)).all()
            for changed in range(length):
                altered = bytearray(data)
                altered[len(base) + changed] ^= 0x80
                assert not _same_bytes(bytes(altered), starts, others, np.array([length], np.int64)).any()


@settings(max_examples=300, deadline=None)
@given(keys=st.lists(st.integers(-(2**63), 2**63 - 1) | st.integers(0, 5), max_size=60), data=st.data())
def test_each_row_s_group_first_is_the_first_row_with_its_key(keys: list[int], data: st.DataObject) -> None:
    rows = sorted(data.draw(st.sets(st.integers(0, max(len(keys) - 1, 0)), max_size=len(keys))))
    key = np.array(keys, np.int64)
    firsts: dict[int, int] = {}
    expected = [firsts.setdefault(keys[row], row) for row in rows]
    assert _group_firsts(np.array(rows, np.int64), key).tolist() == expected
