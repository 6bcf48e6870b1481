"""The numpy length rules and answer keys, held to the scalar rules they are built from."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.framing.rule_tables import REQUEST_RULES, RESPONSE_RULES, padded_bytes
from decoders.modbus.codecs import LAYOUTS
from decoders.modbus.shapes import Column, _request_keys, _response_keys

#: Function codes with a layout, their exception codes, and a few without either.
functions = st.sampled_from(sorted(LAYOUTS)) | st.sampled_from([code | 0x80 for code in LAYOUTS]) | st.integers(0, 255)
segments = st.lists(st.tuples(functions, st.binary(min_size=0, max_size=12)), min_size=1, max_size=40)


def _scalar_length(direction: str, segment: bytes) -> int:
    """What the rule tables hold of ``segment``'s rule: a fixed length, or a one-byte count
    inside the segment; -1 for every other case."""
    layout = LAYOUTS.get(segment[1])
    if layout is None:
        return -1
    rule = getattr(layout, direction)
    if rule.fixed is not None:
        return int(rule.fixed)
    if rule.position is None or rule.size != 1 or rule.position >= len(segment):
        return -1
    return int(rule.base + segment[rule.position])


def _fitted(direction: str, segment: bytes) -> bytes:
    """``segment`` cut or padded with zeros to its rule's length, where it has one (the byte
    count read stays: it lies before the rule's length)."""
    length = _scalar_length(direction, segment)
    return segment if length < 2 else segment[:length] + bytes(max(0, length - len(segment)))


@settings(max_examples=300, deadline=None)
@given(segments)
def test_rule_tables_fit_each_segment_to_its_rule_length(drawn: list[tuple[int, bytes]]) -> None:
    """As drawn (mostly not fitting), and cut to fit where a rule says how: a byte count read
    past a segment's end (from the next segment) never makes it fit."""
    drawn_pieces = [bytes([1, function]) + rest for function, rest in drawn]
    for direction, table in (("request", REQUEST_RULES), ("response", RESPONSE_RULES)):
        for pieces in (drawn_pieces, [_fitted(direction, piece) for piece in drawn_pieces]):
            bounds = np.cumsum([0, *map(len, pieces)]).astype(np.int64)
            starts, lengths = bounds[:-1], np.diff(bounds)
            padded = padded_bytes(b"".join(pieces))
            functions = padded[starts + 1].astype(np.intp)
            found = table.fits(padded, starts, functions, lengths).tolist()
            assert found == [_scalar_length(direction, piece) == len(piece) for piece in pieces]


def _request_keys_by_choose(raw: Column, b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    """The plain reference: every key made, then ``np.choose`` by the function code's group."""
    count, echo = b4 << 8 | b5, (b2 << 24) | (b3 << 16) | (b4 << 8) | b5
    kinds = np.zeros(256, np.intp)
    for kind, functions in enumerate(((1, 2), (3, 4, 23), (5, 6, 15, 16, 22), (8,), (43,)), start=1):
        kinds[list(functions)] = kind
    keys: Column = np.choose(kinds[raw], [np.zeros_like(b2), (count + 7) // 8, 2 * count, echo, b2 << 8 | b3, b2])
    return keys


def _response_keys_by_choose(raw: Column, b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    echo = (b2 << 24) | (b3 << 16) | (b4 << 8) | b5
    kinds = np.zeros(256, np.intp)
    for kind, functions in enumerate(((1, 2, 3, 4, 23), (5, 6, 15, 16, 22), (8,), (43,)), start=1):
        kinds[list(functions)] = kind
    keys: Column = np.choose(kinds[raw], [np.zeros_like(b2), b2, echo, b2 << 8 | b3, b2])
    return keys


@given(st.lists(st.tuples(functions, st.binary(min_size=4, max_size=4)), min_size=0, max_size=60))
def test_answer_keys_are_made_per_group_present_as_by_choosing(frames: list[tuple[int, bytes]]) -> None:
    """Buses of one function (one group: no choice), of several, and frames of none."""
    raw = np.array([function for function, _ in frames], np.intp)
    head = np.array([list(rest) for _, rest in frames], np.int64).reshape(-1, 4)
    b2, b3, b4, b5 = (head[:, k].copy() for k in range(4))
    assert _request_keys(raw, b2, b3, b4, b5).tolist() == _request_keys_by_choose(raw, b2, b3, b4, b5).tolist()
    assert _response_keys(raw, b2, b3, b4, b5).tolist() == _response_keys_by_choose(raw, b2, b3, b4, b5).tolist()
