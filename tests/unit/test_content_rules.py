"""The best parse's rules, one by one, on hand-made segments, over the fast path and the reference."""

from __future__ import annotations

import numpy as np

from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.frame import FrameFlag
from decoders.framer import Framer
from decoders.framing.best_parse import WINDOW, parse_segment
from decoders.framing.content import rule_lengths
from decoders.framing.programme import MAX_EDGE, Context, Piece
from decoders.line import LineSettings

REQUEST = bytes.fromhex("02030C1E0004276C")
RESPONSE = bytes.fromhex("0203080028025801F4000052B0")


def with_crc(body: bytes) -> bytes:
    return body + crc_bytes(body)


def pieces(data: bytes, **kwargs: object) -> list[tuple[bytes, bool, bool, FrameFlag]]:
    """The pieces of a closed segment; the fast path and the reference must agree."""
    options: dict[str, object] = {"closed": True, "timed": True} | kwargs
    results = []
    for fast in (True, False):
        parse = parse_segment(data, Context(**options), fast=fast)  # type: ignore[arg-type]
        results.append([(data[p.start : p.end], p.is_noise, p.crc_ok, p.flags) for p in parse.pieces])
    assert results[0] == results[1]
    return results[0]


def test_rule_lengths_both_directions() -> None:
    assert rule_lengths(REQUEST) == [8, 17]  # as a response, byte 2 (0x0C) would be its byte count
    assert rule_lengths(RESPONSE) == [8, 13]
    assert rule_lengths(bytes.fromhex("02062329000D9270")) == [8]  # echo: one length
    assert rule_lengths(bytes.fromhex("0490045DC2")) == [5]
    assert rule_lengths(bytes.fromhex("0241")) == []  # FC 65: user-defined, no rule


def test_crc_valid_frame_of_wrong_length_is_bad_length() -> None:
    odd = with_crc(bytes.fromhex("0203000A0001FF"))  # FC3 request with a byte too many
    assert pieces(odd) == [(odd, False, True, FrameFlag.BAD_LENGTH)]


def test_user_defined_function_found_by_crc_search() -> None:
    custom = with_crc(bytes.fromhex("0541DEADBEEF01"))
    assert pieces(REQUEST + custom) == [(REQUEST, False, True, FrameFlag.NONE), (custom, False, True, FrameFlag.NONE)]
    assert pieces(custom + REQUEST) == [(custom, False, True, FrameFlag.NONE), (REQUEST, False, True, FrameFlag.NONE)]


def test_altivar_fc43_negative_answer() -> None:
    negative = with_crc(bytes([2, 0xAB, 0x0E, 0x01]))
    request = bytes.fromhex("022B0E01003477")
    assert pieces(request + negative) == [
        (request, False, True, FrameFlag.NONE),
        (negative, False, True, FrameFlag.NONE),
    ]


def test_mei_13_has_no_length_rule_and_is_searched() -> None:
    canopen = with_crc(bytes.fromhex("072B0D0001020304"))
    assert pieces(canopen + REQUEST) == [(canopen, False, True, FrameFlag.NONE), (REQUEST, False, True, FrameFlag.NONE)]


def test_stray_byte_before_a_frame() -> None:
    assert pieces(b"\xff" + REQUEST) == [(b"\xff", True, False, FrameFlag.NONE), (REQUEST, False, True, FrameFlag.NONE)]


def test_zero_glitch_after_a_frame_is_not_part_of_it() -> None:
    assert pieces(RESPONSE + b"\x00\x00") == [
        (RESPONSE, False, True, FrameFlag.NONE),
        (b"\x00\x00", True, False, FrameFlag.NONE),
    ]


def test_damaged_frame_between_valid_ones() -> None:
    damaged = bytearray(RESPONSE)
    damaged[5] ^= 0x10
    result = pieces(REQUEST + bytes(damaged) + REQUEST)
    assert [(p[0], p[2]) for p in result] == [(REQUEST, True), (bytes(damaged), False), (REQUEST, True)]


def test_truncated_at_capture_end_and_mid_frame_start() -> None:
    assert pieces(RESPONSE[:9], at_capture_end=True) == [(RESPONSE[:9], False, False, FrameFlag.TRUNCATED)]
    # 8 bytes fit an FC 3 request, but after an open FC 3 request they are its answer, cut short.
    assert pieces(REQUEST + RESPONSE[:8]) == [(REQUEST, False, True, FrameFlag.NONE),
                                              (RESPONSE[:8], False, False, FrameFlag.TRUNCATED)]
    assert pieces(RESPONSE[4:] + REQUEST, at_capture_start=True) == [
        (RESPONSE[4:], True, False, FrameFlag.NONE),
        (REQUEST, False, True, FrameFlag.NONE),
    ]


def test_a_searched_length_no_boundary_supports_is_no_frame_start() -> None:
    """An FC 8 echo cut short (its CRC never came) whose bytes, with those of the write after
    it, pass the CRC 27 bytes on, inside the write: that length ends where nothing supports it,
    so it is no reading, and the echo is a damaged frame (not noise, as where a frame starts)."""
    write = bytes.fromhex("0110000100060c0000000070870000000000003b6b")
    echo = bytes.fromhex("0508000012345678")
    request = with_crc(bytes.fromhex("0103000A0002"))
    assert crc_bytes((echo + write)[:25]) == b"\x00\x00"  # the length CRC search finds
    assert pieces(request + echo + write) == [(request, False, True, FrameFlag.NONE),
                                              (echo, False, False, FrameFlag.NONE),
                                              (write, False, True, FrameFlag.NONE)]


def test_only_a_frame_at_the_capture_s_end_may_be_cut_off_by_it() -> None:
    """Before the capture's last frame, a damaged frame whose length fits a rule fits it (+4),
    as when the capture goes on (the streaming parse commits it before the end is known)."""
    damaged = bytearray(REQUEST)
    damaged[3] ^= 0x01  # an FC 3 request of 8 bytes, 17 as an answer: at the end, maybe cut off
    for at_end in (False, True):
        assert pieces(bytes(damaged) + REQUEST + RESPONSE, at_capture_end=at_end)[0] == (
            bytes(damaged), False, False, FrameFlag.NONE)
    assert pieces(bytes(damaged), at_capture_end=True) == [(bytes(damaged), False, False, FrameFlag.TRUNCATED)]


def test_garbage_without_a_plausible_header_is_noise() -> None:
    junk = bytes.fromhex("FFFE112233")
    assert pieces(junk) == [(junk, True, False, FrameFlag.NONE)]


def test_open_segment_is_committed_up_to_what_bytes_to_come_cannot_change() -> None:
    data = REQUEST * 200
    parse = parse_segment(data, Context(closed=False))
    assert parse.consumed <= len(data) - MAX_EDGE
    assert all(isinstance(p, Piece) and p.end <= parse.consumed for p in parse.pieces)
    assert parse.consumed >= len(data) - MAX_EDGE - 2 * len(REQUEST)


def test_open_segment_without_anchors_is_committed_window_by_window() -> None:
    broadcast = with_crc(bytes.fromhex("0006000A0001"))  # address 0: never an anchor
    data = broadcast * 300
    parse = parse_segment(data, Context(closed=False))
    assert parse.consumed >= len(data) - WINDOW
    assert [data[p.start : p.end] for p in parse.pieces] == [broadcast] * (parse.consumed // len(broadcast))


def test_framer_memory_stays_bounded_without_any_silence() -> None:
    """A host capture of a busy bus may never show a 100 ms gap: what the framer holds stays bounded."""
    line = LineSettings.parse("115200 8N1")
    framer = Framer(line, TimingQuality.HOST)
    rng = np.random.default_rng(1)
    held = []
    t = 0
    for _ in range(200):
        frames = b"".join(REQUEST + RESPONSE for _ in range(20)) + bytes(rng.integers(0, 256, 5, dtype=np.uint8))
        t += 1_000_000
        framer.feed(ChunkBatch.from_chunks(list(exact_chunks([Transmission(frames, 0)], line, t))))
        held.append(len(framer._data))
    assert max(held) <= MAX_EDGE + 2 * (len(REQUEST) + len(RESPONSE)) + 5
