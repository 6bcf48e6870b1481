"""Hypothesis: segments of two frames (a fast answer) or of a frame and a few stray bytes
(a glitch), which the framer cuts in bulk, are cut as the content parser cuts them."""

from __future__ import annotations

import random
from collections.abc import Callable
from unittest import mock

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pymodbus.pdu import file_message as fm
from pymodbus.pdu import mei_message as mei

from benchmarks.bench_framing import register_read_at_0x02xx
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import Chunk, ChunkBatch
from decoders.crc import crc_bytes
from decoders.framer import Framer
from decoders.framing.best_parse import clean_frame_end, parse_segment
from decoders.framing.fast import (
    clean_frame_ends,
    clean_whole,
    frame_pair_segments,
    has_own_rule,
    single_frame_segments,
)
from decoders.line import LineSettings
from decoders.modbus.codecs import LAYOUTS
from tests.corpus import adu, exchange
from tests.property.test_framer_properties import LINES, T0


def frames(chunks: list[Chunk], line: LineSettings, *, fast: bool, batch: int = 5) -> list[tuple[object, ...]]:
    framer = Framer(line, fast=fast)
    out = []
    for start in range(0, len(chunks), batch):
        out.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + batch])))
    out.extend(framer.flush())
    return [(f.data, f.t_start_ns, f.t_end_ns, f.flags, f.crc_ok, f.is_noise, f.idle_before_ns) for f in out]


@st.composite
def tight_exchanges(draw: st.DrawFn) -> tuple[LineSettings, list[Chunk]]:
    """Requests and answers (pymodbus-built), segment by segment: a frame alone, with its
    answer sooner than t3.5, or with 1..3 stray bytes after it; pauses inside some frames;
    stray bytes alone."""
    line = draw(LINES)
    rng = random.Random(draw(st.integers(0, 2**32 - 1)))
    margin = 3  # ns: 1 ns rounding of byte times never moves a decision made at a threshold
    short = st.integers(0, int(line.t3_5_ns) - margin).filter(lambda s: abs(s - line.t1_5_ns) > margin)
    apart = st.integers(int(line.t3_5_ns) + margin, int(3 * line.t3_5_ns))

    def transmission(data: bytes, idle: int) -> Transmission:
        pause = draw(st.integers(0, 5)) == 0 and len(data) > 1
        gaps = draw(st.dictionaries(st.integers(1, len(data) - 1), short, min_size=1, max_size=1)) if pause else {}
        return Transmission(data, idle, gaps)

    transmissions = []
    for _ in range(draw(st.integers(1, 6))):
        request, answer = exchange(rng, draw(st.integers(1, 247)))
        after = draw(st.sampled_from(["answer", "stray", "apart"]))
        transmissions.append(transmission(request, draw(apart)))
        if after == "stray":
            transmissions.append(Transmission(draw(st.binary(min_size=1, max_size=3)), draw(short)))
        transmissions.append(transmission(answer, draw(short if after == "answer" else apart)))
        if draw(st.booleans()):
            transmissions.append(Transmission(draw(st.binary(min_size=1, max_size=3)), draw(short)))
        if draw(st.integers(0, 4)) == 0:  # stray bytes alone, between silences
            transmissions.append(Transmission(draw(st.binary(min_size=1, max_size=5)), draw(apart)))
    return line, list(exact_chunks(transmissions, line, T0))


#: Found by CI: two FC 8 echoes, then three stray bytes that make the second echo CRC-valid at 11 bytes too.
_ECHO = bytes.fromhex("0108000014ba6eb8")
_ECHO_READ_LONGER = [Chunk(T0 + 13_177_086, _ECHO), Chunk(T0 + 22_343_753, _ECHO),
                     Chunk(T0 + 25_781_253, bytes.fromhex("368016"))]


@settings(max_examples=150, deadline=None)
@given(tight_exchanges())
@example((LineSettings.parse("9600 8E1"), _ECHO_READ_LONGER))
def test_pairs_cut_in_bulk_as_the_parser_cuts_them(capture: tuple[LineSettings, list[Chunk]]) -> None:
    line, chunks = capture
    assert frames(chunks, line, fast=True) == frames(chunks, line, fast=False)


def test_a_fast_answer_and_a_glitch_are_cut_without_the_parser() -> None:
    line = LineSettings.parse("19200 8E1")
    bodies = (bytes.fromhex("0103000A0002"), bytes.fromhex("010304002A0000"))
    request, answer = (body + crc_bytes(body) for body in bodies)
    transmissions = [
        Transmission(request, 0), Transmission(answer, 1_000_000),  # an answer after 1 ms: one segment
        Transmission(request, 10_000_000), Transmission(b"\x00", 0),  # a glitch against the request
        Transmission(answer, 10_000_000),
    ]
    chunks = list(exact_chunks(transmissions, line, T0))
    with mock.patch.object(Framer, "_parse", autospec=True, side_effect=Framer._parse) as parse:
        found = frames(chunks, line, fast=True, batch=len(chunks))
    # Only the held last segment, at the capture's end, is left to the parser.
    closed = [call for call in parse.call_args_list if call.kwargs.get("closed") and not call.kwargs.get("at_end")]
    assert [(f[0], f[4], f[5]) for f in found] == [
        (request, True, False), (answer, True, False), (request, True, False), (b"\x00", False, True),
        (answer, True, False)]
    assert closed == [], "segments of two pieces went through the content parser"
    assert found == frames(chunks, line, fast=False, batch=len(chunks))


def _echo(data: bytes) -> bytes:
    """An FC 8 return-query-data echo of ``data`` (any length) to slave 1."""
    body = bytes([1, 8, 0, 0]) + data
    return body + crc_bytes(body)


def _longer_reading(frame: bytes, extra: int) -> bytes:
    """``extra`` bytes after ``frame`` that make frame + them CRC-valid as one run."""
    body = frame + bytes([extra])
    return bytes([extra]) + crc_bytes(body)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.sampled_from(["echo", "longer", "stray", "read"]), min_size=1, max_size=40),
       st.binary(min_size=1, max_size=6), st.integers(0, 255), LINES, st.sampled_from([1, 2, 50]))
def test_an_echo_read_at_two_lengths_is_left_to_the_programme(
    pieces: list[str], data: bytes, extra: int, line: LineSettings, batch: int
) -> None:
    """An FC 8 echo CRC-valid at its rule length and longer is two readings, not an anchor:
    one segment of such echoes (short: scalar anchors; long: numpy anchors; fed whole or in
    pieces, so anchors are also committed while it is open) is cut as the reference cuts it."""
    echo = _echo(data[:2])
    read = bytes.fromhex("0103000A0002")
    parts = {"echo": echo, "longer": echo + _longer_reading(echo, extra), "stray": bytes([extra]),
             "read": read + crc_bytes(read)}
    stream = b"".join(parts[name] for name in pieces)
    chunks = list(exact_chunks([Transmission(stream[k : k + 7], 0) for k in range(0, len(stream), 7)], line, T0))
    assert frames(chunks, line, fast=True, batch=batch) == frames(chunks, line, fast=False, batch=batch)


def test_a_reading_crossing_an_anchor_s_end_is_weighed_as_the_reference_weighs_it() -> None:
    """Found by the test above: an FC 1 request (0xBA, slave 186) holding an FC 8 echo that is
    CRC-valid at two lengths, the longer one past the request's end, then one byte."""
    stream = bytes.fromhex("ba010800007ea501d0ba81b3ba")
    line = LineSettings.parse("9600 8E1")
    chunks = list(exact_chunks([Transmission(stream[k : k + 7], 0) for k in range(0, len(stream), 7)], line, T0))
    assert frames(chunks, line, fast=True) == frames(chunks, line, fast=False)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.sampled_from(["echo", "longer", "noise"]), min_size=1, max_size=60), st.binary(min_size=1),
       st.integers(0, 255))
def test_clean_frames_found_in_bulk_as_one_by_one(pieces: list[str], data: bytes, extra: int) -> None:
    """The numpy clean-frame ends equal the scalar ones, echoes read at two lengths included."""
    echo = _echo(data[:3])
    parts = {"echo": echo, "longer": echo + _longer_reading(echo, extra), "noise": data}
    stream = b"".join(parts[name] for name in pieces)
    assert clean_frame_ends(stream).tolist() == [clean_frame_end(stream, k, len(stream)) for k in range(len(stream))]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 255), st.sampled_from(sorted(LAYOUTS)) | st.integers(0, 255),
                          st.binary(max_size=12), st.integers(0, 3)), min_size=1, max_size=30))
@example([(1, 8, bytes.fromhex("00001234"), 0), (1, 8, bytes.fromhex("00001234"), 2)])  # echoes
@example([(1, 3, bytes.fromhex("02abcd"), 1)])  # an 8-byte FC 3 request ending in 0x00, and a 7-byte answer
def test_segments_ending_in_zero_are_whole_in_columns_as_one_by_one(
    drawn: list[tuple[int, int, bytes, int]],
) -> None:
    """Segments that pass the CRC (a frame, then up to three 0x00 that keep it passing): whole
    by :func:`clean_whole` only where the scalar clean-frame rule reads the whole segment, FC 8
    echoes left out."""
    segments = []
    for address, function, rest, zeros in drawn:
        body = bytes([address, function]) + rest
        segments.append(body + crc_bytes(body) + bytes(zeros))
    bounds = np.cumsum([0, *map(len, segments)]).astype(np.int64)
    stream = b"".join(segments)
    whole, settled = clean_whole(stream, bounds[:-1], bounds[1:])
    echoes = [segment[1] == 8 and segment[2:4] == b"\0\0" for segment in segments]
    assert settled.tolist() == [not echo for echo in echoes]
    assert whole.tolist() == [clean_frame_end(segment, 0, len(segment)) == len(segment) and not echo
                              for segment, echo in zip(segments, echoes, strict=True)]
    # Of those that fit their rule, settled and not whole: no pair nor frame and stray bytes.
    fitting = np.logical_or(*single_frame_segments(stream, bounds[:-1], bounds[1:], np.ones(len(segments), np.bool_)))
    first_length, _, pair_whole = frame_pair_segments(stream, bounds[:-1], bounds[1:], None)
    assert not (fitting & settled & ~whole & ((first_length > 0) | pair_whole)).any()


def test_an_echo_with_a_longer_reading_is_no_clean_frame() -> None:
    longer = _ECHO + bytes.fromhex("368016")
    assert clean_frame_end(longer, 0, len(longer)) == 0
    assert clean_frame_ends(longer)[0] == 0
    assert clean_frame_end(_ECHO + b"\x36", 0, 9) == 8


def _polling_with_requests_ending_in_zero(exchanges: int) -> list[Chunk]:
    """FC 3 polling of four slaves (4 to 7: slaves 1 to 3 have no such request) whose requests
    end in 0x00 and read as a 7-byte answer and a glitch too (start address 0x02xx), their
    answers drawn anew; every tenth request unanswered at first, then sent again."""
    rng = random.Random(5)
    requests = {slave: (body := register_read_at_0x02xx(slave, ends_in_zero=True)) + crc_bytes(body)
                for slave in range(4, 8)}
    transmissions = []
    for turn in range(exchanges):
        slave = turn % 4 + 4
        answer = bytes([slave, 3, 2 * requests[slave][5]]) + rng.randbytes(2 * requests[slave][5])
        if turn % 10 == 9:  # unanswered, then sent again while it is open
            transmissions.append(Transmission(requests[slave], 9_000_000))
        transmissions.append(Transmission(requests[slave], 9_000_000))
        transmissions.append(Transmission(answer + crc_bytes(answer), 5_000_000))
    return list(exact_chunks(transmissions, LineSettings.parse("19200 8E1"), T0))


def test_a_repeated_segment_is_parsed_once_and_as_the_plain_path_parses_it() -> None:
    chunks = _polling_with_requests_ending_in_zero(200)
    line = LineSettings.parse("19200 8E1")
    with mock.patch("decoders.framer.parse_segment", wraps=parse_segment) as parsed:
        found = frames(chunks, line, fast=True, batch=37)
    segments = [call.args[:3] for call in parsed.call_args_list if call.args[1].closed]
    assert len(segments) == len(set(segments)) < 20  # the four requests, each once in each state
    assert found == frames(chunks, line, fast=False, batch=37)
    requests = [data for data, *_ in found if data.endswith(b"\x00") and len(data) == 8]
    # Sent again while open, a request is a retry, not the answer it awaits and a glitch: its
    # parse depends on the open request as well as on its bytes.
    assert len(requests) == 220 and len(found) == 420
    assert {open_request and open_request[:2] for _, _, open_request in segments} == {None, (5, 3), (7, 3)}


def _ending_in_zero(body_of: Callable[[int], bytes]) -> bytes:
    """The first frame ``body_of(k) + CRC`` (k = 0, 1, ...) whose CRC ends in 0x00."""
    return next(frame for k in range(65536) if (frame := body_of(k) + crc_bytes(body_of(k))).endswith(b"\x00"))


def test_whole_frames_the_tables_leave_out_are_taken_without_the_parser() -> None:
    """Frames ending in 0x00 whose shorter reading fits no rule (a read at 0x00xx, an answer of
    one register), FC 43 and FC 24 exchanges (rules the tables cannot hold): each one segment,
    each taken whole in bulk, as the parser takes them."""
    request = _ending_in_zero(lambda k: bytes([1 + (k >> 8) % 247, 3, 0, k & 0xFF, 0, 1]))
    answer = _ending_in_zero(lambda k: bytes([9, 3, 2, k >> 8, k & 0xFF]))
    device = adu(mei.ReadDeviceInformationRequest(dev_id=9, read_code=1, object_id=0))
    identity = adu(mei.ReadDeviceInformationResponse(dev_id=9, read_code=1, information={0: b"Schneider"}))
    fifo = adu(fm.ReadFifoQueueRequest(dev_id=9, address=16))
    queue = adu(fm.ReadFifoQueueResponse(dev_id=9, values=[7]))
    line = LineSettings.parse("19200 8E1")
    sent = [request, answer, device, identity, fifo, queue] * 3
    chunks = list(exact_chunks([Transmission(frame, 5_000_000) for frame in sent], line, T0))
    with mock.patch("decoders.framer.parse_segment", wraps=parse_segment) as parsed:
        found = frames(chunks, line, fast=True, batch=4)
    # The last segment is held until the capture ends, and parsed then.
    assert not [call for call in parsed.call_args_list if call.args[1].closed and not call.args[1].at_capture_end]
    assert [data for data, *_ in found] == sent
    assert found == frames(chunks, line, fast=False, batch=4)


def test_own_rules_are_told_by_the_function_code_in_place() -> None:
    """FC 43 (and its exception) and FC 24 have rules of their own; a one-byte segment at the
    end of the batch has no function code at all, whatever byte 1 of the batch holds."""
    data = bytes([43, 43, 0, 0, 5, 3, 0, 0, 6, 24, 0, 0, 7, 43 | 0x80, 0, 0, 9])
    starts = np.array([0, 4, 8, 12, 16], np.int64)
    assert has_own_rule(data, starts).tolist() == [True, False, True, True, False]
