"""Hypothesis: records built in columns equal records built one by one.

:func:`join_rows` against concatenating each row's pieces; :func:`hex_texts` against
``bytes.hex``; the columnar protobuf varints and ``foxglove.Log`` messages against the
one-by-one encoder.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sniffer.encoding.rows import Pieces, hex_texts, join_rows, number_texts, or_null
from sniffer.exports.foxglove_log import LogEncoder, _varint, varint_pieces

NONE = -1
pieces = st.binary(max_size=12)


@st.composite
def tables(draw: st.DrawFn) -> tuple[list[bytes | list[bytes]], int]:
    count = draw(st.integers(0, 20))
    columns = draw(st.lists(st.one_of(pieces, st.lists(pieces, min_size=count, max_size=count)), max_size=8))
    return columns, count


@given(tables(), st.integers(0, 40))
def test_join_rows_is_each_row_concatenated(table: tuple[list[bytes | list[bytes]], int], reserved: int) -> None:
    columns, count = table
    rows = join_rows(columns, count, reserved)
    assert len(rows) == count
    for row in range(count):
        expected = b"".join(column if isinstance(column, bytes) else column[row] for column in columns)
        assert rows.row(row) == expected
        start = int(rows.offsets[row])
        assert rows.data[start : start + reserved] == bytes(reserved)
    assert int(rows.offsets[-1]) == len(rows.data)


@given(st.lists(st.binary(max_size=40), max_size=30), st.binary(max_size=5), st.booleans())
def test_hex_texts_are_bytes_hex(frames: list[bytes], before: bytes, quoted: bool) -> None:
    data = before + b"".join(frames)
    offsets = np.cumsum([len(before), *map(len, frames)]).astype(np.int64)
    texts = hex_texts(data, offsets, quoted=quoted)
    quote = b'"' if quoted else b""
    assert texts == [quote + frame.hex().encode() + quote for frame in frames]
    assert texts.sizes.tolist() == list(map(len, texts))


@given(st.lists(st.one_of(st.integers(-(1 << 62), 1 << 62), st.just(NONE)), max_size=30))
def test_number_texts_or_null_are_json(values: list[int]) -> None:
    column = np.array(values, np.int64)
    texts = or_null(number_texts(column), column, NONE)
    assert texts == [b"null" if value == NONE else str(value).encode() for value in values]
    assert texts.sizes.tolist() == list(map(len, texts))


@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=30))
def test_number_texts_of_floats_are_repr_with_their_sizes(values: list[float]) -> None:
    texts = number_texts(np.array(values, np.float64))
    assert texts == [repr(value).encode() for value in values]
    assert texts.sizes.tolist() == list(map(len, texts))


@given(st.lists(st.one_of(st.integers(0, (1 << 35) - 1), st.integers(-(1 << 63), (1 << 63) - 1)), max_size=30))
def test_varint_pieces_are_the_varints(values: list[int]) -> None:
    found = varint_pieces(np.array(values, np.int64))
    assert found == [_varint(value) for value in values]
    assert found.sizes.tolist() == [len(_varint(value)) for value in values]


def _fields(message: bytes) -> dict[int, int | bytes]:
    """A protobuf message's fields by number (varints and length-delimited only)."""
    fields: dict[int, int | bytes] = {}
    offset = 0
    while offset < len(message):
        key, offset = _read_varint(message, offset)
        if key & 7 == 0:
            fields[key >> 3], offset = _read_varint(message, offset)
        else:
            assert key & 7 == 2
            size, offset = _read_varint(message, offset)
            fields[key >> 3], offset = message[offset : offset + size], offset + size
    assert offset == len(message)
    return fields


def _read_varint(data: bytes, offset: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[offset]
        value, shift, offset = value | (byte & 0x7F) << shift, shift + 7, offset + 1
        if not byte & 0x80:
            return value, offset


@given(
    st.lists(
        st.tuples(
            st.integers(0, 1 << 62),
            st.integers(0, 5),
            st.text(max_size=30),
            st.sampled_from(["slave 1", "noise", "slave 247"]),
        ),
        max_size=20,
    )
)
def test_log_rows_decode_to_what_was_given(entries: list[tuple[int, int, str, str]]) -> None:
    """``foxglove.Log``: timestamp {seconds, nanos}, level, message, name; zeros left out (proto3)."""
    t_ns = np.array([entry[0] for entry in entries], np.int64)
    levels = np.array([entry[1] for entry in entries], np.uint8)
    texts = [entry[2].encode() for entry in entries]
    names = ["slave 1", "noise", "slave 247"]
    keys = np.array([names.index(entry[3]) for entry in entries], np.int64)
    rows = LogEncoder(names).rows(t_ns, levels, [b"#", texts], keys)
    for row, (t, level, text, name) in enumerate(entries):
        fields = _fields(rows.row(row))
        timestamp = _fields(fields.pop(1))  # type: ignore[arg-type]
        assert timestamp == {key: value for key, value in ((1, t // 10**9), (2, t % 10**9)) if value}
        assert (
            fields == {2: level, 3: b"#" + text.encode(), 4: name.encode()}
            if level
            else fields == {3: b"#" + text.encode(), 4: name.encode()}
        )


@given(st.lists(st.binary(max_size=6), max_size=60), st.data())
def test_fill_puts_the_piece_at_the_rows(items: list[bytes], data: st.DataObject) -> None:
    """One by one for a few rows, through numpy for many: the same pieces and sizes."""
    rows = sorted(data.draw(st.sets(st.integers(0, len(items) - 1))) if items else set())
    pieces = Pieces(list(items), np.fromiter(map(len, items), np.int64, len(items)))
    pieces.fill(np.array(rows, np.int64), b"null")
    assert pieces == [b"null" if row in rows else item for row, item in enumerate(items)]
    assert pieces.sizes.tolist() == list(map(len, pieces))
