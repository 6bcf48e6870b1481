"""The timing framer on hand-made timings, at and around t1.5 and t3.5."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import Chunk, ChunkBatch
from decoders.crc import crc_bytes
from decoders.frame import Frame, FrameFlag
from decoders.framer import Framer
from decoders.line import LineSettings

LINES = [LineSettings.parse(t) for t in ("9600 8E1", "19200 8E1", "115200 8N1")]
T0 = 1_700_000_000_000_000_000
REQUEST = bytes.fromhex("02030C1E0004276C")
RESPONSE = bytes.fromhex("0203080028025801F4000052B0")


def frame_all(chunks: list[Chunk], line: LineSettings, batch_size: int = 1000) -> list[Frame]:
    framer = Framer(line)
    frames: list[Frame] = []
    for start in range(0, len(chunks), batch_size):
        frames.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + batch_size])))
    frames.extend(framer.flush())
    return frames


def two_frames(line: LineSettings, silence_ns: int) -> list[Frame]:
    chunks = list(exact_chunks([Transmission(REQUEST, 0), Transmission(RESPONSE, silence_ns)], line, T0))
    return frame_all(chunks, line)


def one_frame_with_gap(line: LineSettings, gap_ns: int) -> list[Frame]:
    chunks = list(exact_chunks([Transmission(RESPONSE, 0, {5: gap_ns})], line, T0))
    return frame_all(chunks, line)


@pytest.mark.parametrize("line", LINES, ids=lambda line: line.format())
class TestThresholds:
    def test_silence_exactly_t3_5_splits(self, line: LineSettings) -> None:
        frames = two_frames(line, round(line.t3_5_ns))
        assert [f.data for f in frames] == [REQUEST, RESPONSE]
        assert all(f.crc_ok and f.flags == FrameFlag.NONE for f in frames)

    def test_silence_just_above_t3_5_splits(self, line: LineSettings) -> None:
        assert len(two_frames(line, round(line.t3_5_ns) + 1_000)) == 2

    def test_silence_just_below_t3_5_is_split_by_content(self, line: LineSettings) -> None:
        frames = two_frames(line, round(line.t3_5_ns) - 1_000)
        assert [(f.data, f.flags, f.crc_ok) for f in frames] == [
            (REQUEST, FrameFlag.NONE, True),
            (RESPONSE, FrameFlag.SHORT_IDLE, True),
        ]

    def test_gap_exactly_t1_5_is_not_flagged(self, line: LineSettings) -> None:
        frames = one_frame_with_gap(line, round(line.t1_5_ns))
        assert [(f.data, f.flags) for f in frames] == [(RESPONSE, FrameFlag.NONE)]

    def test_gap_just_below_t1_5_is_not_flagged(self, line: LineSettings) -> None:
        frames = one_frame_with_gap(line, round(line.t1_5_ns) - 1_000)
        assert [(f.data, f.flags) for f in frames] == [(RESPONSE, FrameFlag.NONE)]

    def test_gap_just_above_t1_5_is_flagged(self, line: LineSettings) -> None:
        frames = one_frame_with_gap(line, round(line.t1_5_ns) + 1_000)
        assert [(f.data, f.flags, f.crc_ok) for f in frames] == [(RESPONSE, FrameFlag.GAP_1_5, True)]

    def test_gap_just_below_t3_5_is_flagged_not_split(self, line: LineSettings) -> None:
        frames = one_frame_with_gap(line, round(line.t3_5_ns) - 1_000)
        assert [(f.data, f.flags) for f in frames] == [(RESPONSE, FrameFlag.GAP_1_5)]


def test_times_and_idle() -> None:
    line = LineSettings.parse("19200 8E1")
    idle = 5_000_000
    frames = two_frames(line, idle)
    request, response = frames
    assert request.t_start_ns == T0
    assert request.t_end_ns == T0 + round(8 * line.char_time_ns)
    assert request.idle_before_ns is None
    assert response.idle_before_ns == pytest.approx(idle, abs=1)
    assert response.t_end_ns - response.t_start_ns == pytest.approx(13 * line.char_time_ns, abs=1)
    assert [f.index for f in frames] == [0, 1]


def test_frame_spanning_batches_is_held_until_its_end_is_known() -> None:
    line = LineSettings.parse("19200 8E1")
    chunks = list(exact_chunks([Transmission(REQUEST, 0), Transmission(RESPONSE, 10_000_000)], line, T0))
    framer = Framer(line)
    assert len(framer.feed(ChunkBatch.from_chunks(chunks[:1]))) == 0
    first = list(framer.feed(ChunkBatch.from_chunks(chunks[1:])))
    assert [f.data for f in first] == [REQUEST]
    assert [f.data for f in framer.flush()] == [RESPONSE]
    assert len(framer.flush()) == 0


def test_empty_input() -> None:
    framer = Framer(LineSettings.parse("9600 8N1"))
    assert len(framer.feed(ChunkBatch.empty())) == 0
    assert len(framer.flush()) == 0


def test_every_byte_in_exactly_one_frame() -> None:
    line = LineSettings.parse("9600 8N1")
    rng = np.random.default_rng(3)
    transmissions = []
    for _ in range(200):
        body = bytes(rng.integers(0, 256, int(rng.integers(1, 40)), dtype=np.uint8))
        transmissions.append(Transmission(body + crc_bytes(body), int(rng.integers(0, 8_000_000))))
    chunks = list(exact_chunks(transmissions, line, T0))
    frames = frame_all(chunks, line, batch_size=7)
    assert b"".join(f.data for f in frames) == b"".join(c.data for c in chunks)


def test_close_idle_emits_the_last_frame_once_the_line_is_quiet() -> None:
    line = LineSettings.parse("19200 8E1")
    framer = Framer(line)
    chunks = list(exact_chunks([Transmission(REQUEST, 0)], line, T0))
    assert len(framer.feed(ChunkBatch.from_chunks(chunks))) == 0
    end = chunks[-1].t_end_ns
    assert len(framer.close_idle(end + round(line.t3_5_ns) - 10)) == 0
    assert [f.data for f in framer.close_idle(end + round(line.t3_5_ns) + 10)] == [REQUEST]
    assert len(framer.flush()) == 0


def byte_chunks(line: LineSettings, pieces: list[tuple[bytes, float, tuple[int, ...]]]) -> list[Chunk]:
    """A chunk per byte, back to back inside a piece; each piece after ``gap`` characters of
    silence, its bytes at ``framing`` positions marked with a framing error."""
    chunks, t = [], T0
    for data, gap, framing in pieces:
        t += round(gap * line.char_time_ns)
        for position, byte in enumerate(data):
            t += round(line.char_time_ns)
            chunks.append(Chunk(t, bytes([byte]), ((0, 1),) if position in framing else ()))
    return chunks


@pytest.mark.parametrize("fast", [True, False])
def test_a_glitch_with_a_framing_error_is_noise_before_a_damaged_answer(fast: bool) -> None:
    """A spike read as a character with a framing error half a character before a damaged
    answer: without the error the glitch would be the answer's slave address; with it, it is
    noise and the damaged answer starts after it (README, "Framing")."""
    line = LineSettings.parse("19200 8E1")
    request = bytes.fromhex("010300000002") + crc_bytes(bytes.fromhex("010300000002"))
    body = bytes.fromhex("010304000A000B")
    damaged = bytearray(body + crc_bytes(body))
    damaged[4] ^= 0x10
    results = []
    for framing in ((), (0,)):
        chunks = byte_chunks(line, [(request, 10, ()), (b"\x00", 5, framing), (bytes(damaged), 0.5, ())])
        framer = Framer(line, fast=fast)
        frames = [*framer.feed(ChunkBatch.from_chunks(chunks)), *framer.flush()]
        results.append([(f.data, f.is_noise, FrameFlag.UART_ERROR in f.flags) for f in frames])
    assert results[0][1] == (b"\x00" + bytes(damaged), False, False)
    assert results[1][1:] == [(b"\x00", True, True), (bytes(damaged), False, False)]


@pytest.mark.parametrize("fast", [True, False])
def test_a_length_by_crc_search_may_start_where_a_frame_ends(fast: bool) -> None:
    """An FC 11 request and, with no silence after it, a 4-byte CRC-valid run of an unknown
    function (found by CRC search): the request's end supports the search on both paths (the
    plain programme once searched only at segment starts and pauses; hypothesis found it)."""
    line = LineSettings.parse("9600 8E1")
    chunks = [Chunk(1_600_000_000_004_583_333, b"\x01\x0bA\xe7"), Chunk(1_600_000_000_009_166_666, b"\x00\r\xc0u")]
    framer = Framer(line, fast=fast)
    frames = [*framer.feed(ChunkBatch.from_chunks(chunks)), *framer.flush()]
    assert [(f.data.hex(), f.is_noise, f.crc_ok) for f in frames] == [("010b41e7", False, True),
                                                                      ("000dc075", False, True)]


def _adu(body_hex: str) -> bytes:
    body = bytes.fromhex(body_hex)
    return body + crc_bytes(body)


@pytest.mark.parametrize("batch", [1, 2, 5])
def test_the_rest_of_an_open_segment_knows_a_frame_ended_where_it_begins(batch: int) -> None:
    """A long segment (answers sooner than t3.5) is committed frame by frame while open; the
    four stray bytes after its first frame were read as a damaged frame once that frame had
    been committed, and as noise (a glitch against a frame) by the parse of the whole
    segment. Found by hypothesis (tests/property/test_frame_pairs.py, an earlier strategy)."""
    line = LineSettings.parse("9600 8E1")
    request, answer = _adu("010461c4001d"), _adu("01043a" + "00" * 58)
    stray = bytes.fromhex("00010000")
    transmissions = [Transmission(request, 0), Transmission(stray, 0), Transmission(answer, 0),
                     Transmission(b"\x00", 0)]
    for k in range(14):  # 2 ms apart at 9600 Bd (t3.5 = 4 ms): one segment of 300 bytes
        transmissions += [Transmission(_adu(f"0103{k:04x}0002"), 2_000_000),
                          Transmission(_adu(f"010304{k:08x}"), 2_000_000)]
    chunks = list(exact_chunks(transmissions, line, T0))

    def frames(fast: bool, size: int) -> list[tuple[bytes, bool, FrameFlag]]:
        framer = Framer(line, fast=fast)
        out = []
        for start in range(0, len(chunks), size):
            out.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + size])))
        out.extend(framer.flush())
        return [(f.data, f.is_noise, f.flags) for f in out]

    found = frames(True, batch)
    assert found[1] == (stray, True, FrameFlag.NONE)
    assert found == frames(False, len(chunks))
