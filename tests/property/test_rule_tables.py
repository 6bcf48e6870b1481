"""The numpy length rules and answer keys, held to the scalar rules they are built from."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.framing.fast import REQUEST_RULES, RESPONSE_RULES, padded_bytes
from decoders.modbus.layouts import LAYOUTS
from decoders.modbus.shapes import _chosen

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


@settings(max_examples=300, deadline=None)
@given(segments)
def test_rule_tables_give_each_segment_its_rule_length(drawn: list[tuple[int, bytes]]) -> None:
    pieces = [bytes([1, function]) + rest for function, rest in drawn]
    bounds = np.cumsum([0, *map(len, pieces)]).astype(np.int64)
    starts, lengths = bounds[:-1], np.diff(bounds)
    padded = padded_bytes(b"".join(pieces))
    functions = padded[starts + 1].astype(np.intp)
    for direction, table in (("request", REQUEST_RULES), ("response", RESPONSE_RULES)):
        found = table.lengths(padded, starts, functions, lengths).tolist()
        assert found == [_scalar_length(direction, piece) for piece in pieces]


@given(st.lists(st.integers(0, 4), min_size=0, max_size=50), st.integers(0, 2**31))
def test_chosen_keys_are_what_choose_picks(kinds: list[int], seed: int) -> None:
    rng = np.random.default_rng(seed)
    choices = [rng.integers(0, 1 << 32, len(kinds)) for _ in range(5)]
    picked = np.array(kinds, np.intp)
    assert _chosen(picked, choices).tolist() == np.choose(picked, choices).tolist()
