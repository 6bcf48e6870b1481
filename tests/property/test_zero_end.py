"""Hypothesis: a segment that is one frame ending in 0x00 and, a byte shorter, a frame of the
other direction and a glitch (:mod:`decoders.framing.zero_end`) is cut as the programme cuts it,
after every kind of open request (none, another slave's, the one it answers, the same request
again), in every context; and the shortcut takes such segments, not others."""

from __future__ import annotations

from functools import reduce
from operator import xor

from fastcrc import crc16
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.crc import crc_bytes
from decoders.framing.best_parse import parse_segment
from decoders.framing.content import OpenRequest, rule_lengths
from decoders.framing.evidence import CrcSearch
from decoders.framing.programme import Context
from decoders.framing.zero_end import nothing_read_after_first_byte, weighed_zero_end
from decoders.uss import STX, uss_length


def _ending_in_zero(head: bytes, seed: int, rest: bytes = b"", *, first_byte: range = range(256)) -> bytes:
    """``head`` + a two-byte word + ``rest`` + its CRC, the word the first (in an order ``seed``
    picks, its first byte in ``first_byte``) whose CRC ends in 0x00 (one word in 256 gives one)."""
    for k in range(1 << 16):
        word = (seed + 40_503 * k) & 0xFFFF
        if word >> 8 not in first_byte:
            continue
        body = head + word.to_bytes(2, "big") + rest
        crc = crc_bytes(body)
        if crc[1] == 0:
            return body + crc
    raise AssertionError("no word gives a CRC ending in 0x00")


@st.composite
def ambiguous_segments(draw: st.DrawFn) -> bytes:
    """A frame ending in 0x00 whose first bytes, one shorter, fit the other direction's rule:
    a read request at 0x02xx (an answer of two bytes and a glitch), a read answer of four bytes
    (a request and a glitch), an FC 15/16 request of no data (an 8-byte answer and a glitch)."""
    slave = draw(st.sampled_from([1, 17, 247, 0, 250]))
    kind = draw(st.sampled_from(["read request", "read answer", "write request"]))
    seed = draw(st.integers(0, 0xFFFF))
    if kind == "read request":  # the quantity is the free word
        return _ending_in_zero(bytes([slave, draw(st.sampled_from([1, 2, 3, 4])), 2, draw(st.integers(0, 255))]),
                               seed)
    if kind == "read answer":  # the last two data bytes are; as a request, a quantity in range or not
        function, first = draw(st.sampled_from([1, 2, 3, 4])), draw(st.integers(0, 255))
        plausible = draw(st.booleans())
        return _ending_in_zero(bytes([slave, function, 4, first, 0 if plausible else draw(st.integers(1, 255))]),
                               seed, first_byte=range(1, 126) if plausible else range(256))
    # The address is the free word; the quantity and a byte count of 0 follow.
    return _ending_in_zero(bytes([slave, draw(st.sampled_from([15, 16]))]), seed,
                           draw(st.binary(min_size=2, max_size=2)) + b"\x00")


def _open_requests(segment: bytes) -> st.SearchStrategy[OpenRequest]:
    slave, function = segment[0], segment[1]
    request = segment if len(segment) == 8 and function in (1, 2, 3, 4) else segment[:-1]
    return st.sampled_from([
        None,
        (slave, function, bytes([slave, function]) + bytes(6)),  # the request this answers
        (slave, function, request),  # this very request, sent again
        ((slave + 1) & 0xFF, function, bytes([(slave + 1) & 0xFF, function]) + bytes(6)),  # another slave's
        (slave, function ^ 1, bytes([slave, function ^ 1]) + bytes(6)),  # another function
    ])


_CONTEXTS = st.builds(Context, closed=st.just(True), timed=st.booleans(), at_capture_start=st.booleans(),
                      at_capture_end=st.booleans(), follows_frame=st.booleans())


def _cut(segment: bytes, context: Context, open_request: OpenRequest, *, fast: bool) -> tuple[object, ...]:
    parse = parse_segment(segment, context, open_request, fast=fast)
    pieces = [(p.start, p.end, p.is_noise, p.crc_ok, int(p.flags), p.protocol) for p in parse.pieces]
    return pieces, parse.consumed, parse.open_request


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_the_shortcut_cuts_as_the_programme(data: st.DataObject) -> None:
    segment = data.draw(ambiguous_segments())
    context = data.draw(_CONTEXTS)
    open_request = data.draw(_open_requests(segment))
    # Taken unless a CRC-valid span starts inside (one such segment in about 5 000).
    readable_inside = not nothing_read_after_first_byte(segment, CrcSearch(segment))
    assert (weighed_zero_end(segment, context, open_request) is None) == readable_inside
    assert _cut(segment, context, open_request, fast=True) == _cut(segment, context, open_request, fast=False)


@settings(max_examples=200, deadline=None)
@given(st.data(), st.binary(min_size=1, max_size=6))
def test_segments_with_more_to_read_are_left_to_the_programme(data: st.DataObject, extra: bytes) -> None:
    """A pause inside, a framing error, or a valid frame after the first byte: the programme weighs."""
    segment = data.draw(ambiguous_segments())
    open_request = data.draw(_open_requests(segment))
    for context in (Context((3,), closed=True, timed=True), Context(closed=True, framing_errors=(2,)),
                    Context(closed=False)):
        assert weighed_zero_end(segment, context, open_request) is None
    glued = segment[:-1] + extra + crc_bytes(segment[:-1] + extra)  # a CRC-valid span from the start
    longer = segment + glued
    if crc16.modbus(longer[1:]) != 0:
        assert weighed_zero_end(longer, Context(closed=True), open_request) is None
        assert _cut(longer, Context(closed=True), open_request, fast=True) == _cut(
            longer, Context(closed=True), open_request, fast=False)


def test_the_two_readings_go_both_ways() -> None:
    """An FC 3 answer ending in 0x00 after its request is the answer; with no request open, a
    request and a glitch; the same request sent again is the retry and a glitch."""
    # As a request, it asks for 1 to 125 registers: a plausible one.
    answer = _ending_in_zero(bytes([17, 3, 4, 0x12, 0x00]), 7, first_byte=range(1, 126))
    context = Context(closed=True, timed=True)
    asked: OpenRequest = (17, 3, bytes.fromhex("1103000000020000"))
    assert weighed_zero_end(answer, context, asked) == (False, None)
    assert weighed_zero_end(answer, context, None) == (True, (17, 3, answer[:-1]))
    assert weighed_zero_end(answer, context, (17, 3, answer[:-1])) == (True, (17, 3, answer[:-1]))
    # As a request, too many registers: the answer, even with no request open.
    implausible = _ending_in_zero(bytes([17, 3, 4, 0x12, 0x34]), 7)
    assert weighed_zero_end(implausible, context, None) == (False, None)


def test_a_crc_valid_span_inside_leaves_the_segment_to_the_programme() -> None:
    """An FC 2 answer ending in 0x00 whose bytes 3 to 6 pass the CRC on their own (found by a
    search of 3 M random answers: 2 of the 11 700 ending in 0x00)."""
    segment = bytes.fromhex("600204705aa44b8b00")
    assert crc16.modbus(segment) == 0 and crc16.modbus(segment[3:7]) == 0
    for open_request in (None, (0x60, 2, bytes.fromhex("6002000000200000"))):
        assert weighed_zero_end(segment, Context(closed=True), open_request) is None
        assert _cut(segment, Context(closed=True), open_request, fast=True) == _cut(
            segment, Context(closed=True), open_request, fast=False)


def test_a_uss_telegram_inside_leaves_the_segment_to_the_programme() -> None:
    """An FC 23 request ending in 0x00 (its first 20 bytes fit an answer of 15 bytes) that
    writes a NORD USS telegram as its data."""
    telegram = bytes([STX, 6, 3, 0x12, 0x34, 0x56, 0x78])
    telegram += bytes([reduce(xor, telegram)])
    assert uss_length(telegram) == 8
    # Read 15 registers at 0x0F00 (byte 2: 15, an answer's byte count), write 4 at a free word.
    segment = _ending_in_zero(bytes([17, 23, 15, 0x00, 0x00, 0x0F]), 1, bytes([0x00, 0x04, 8]) + telegram)
    assert len(segment) == 21 and rule_lengths(segment) == [21, 20]
    assert weighed_zero_end(segment, Context(closed=True), None) is None
    assert _cut(segment, Context(closed=True), None, fast=True) == _cut(segment, Context(closed=True), None,
                                                                         fast=False)
