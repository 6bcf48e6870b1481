"""Hypothesis: how an exact capture is cut into chunks and batches never changes its frames."""

from __future__ import annotations

import os
from itertools import pairwise

from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import Chunk, ChunkBatch
from decoders.crc import crc_bytes
from decoders.framer import Framer
from decoders.line import LineSettings

T0 = 1_600_000_000_000_000_000
LINES = st.sampled_from([LineSettings.parse(t) for t in ("9600 8E1", "19200 8E1", "115200 8N1")])


def silences(line: LineSettings) -> st.SearchStrategy[int]:
    """Silences up to 3 x t3.5, but not within 3 ns of a threshold: 1 ns rounding of a
    re-chunked capture's times may legitimately move a decision made at the threshold."""
    thresholds = (line.t1_5_ns, line.t3_5_ns)
    return st.integers(0, int(3 * line.t3_5_ns)).filter(lambda s: all(abs(s - t) > 3 for t in thresholds))


def close(a: list[tuple[object, ...]], b: list[tuple[object, ...]]) -> bool:
    """Equal frames; times equal to within the 1 ns rounding of re-chunked times."""
    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        if (x[0], x[3], x[4]) != (y[0], y[3], y[4]):
            return False
        for i in (1, 2, 5):
            if (x[i] is None) != (y[i] is None) or (x[i] is not None and abs(int(x[i]) - int(y[i])) > 1):  # type: ignore[call-overload]
                return False
    return True


@st.composite
def captures(draw: st.DrawFn) -> tuple[LineSettings, list[Chunk]]:
    line = draw(LINES)
    transmissions = []
    for _ in range(draw(st.integers(1, 12))):
        body = draw(st.binary(min_size=1, max_size=40))
        data = body + crc_bytes(body)
        gaps = draw(st.dictionaries(st.integers(1, len(data) - 1), silences(line), max_size=2))
        idle = draw(silences(line))
        transmissions.append(Transmission(data, idle, gaps))
    return line, list(exact_chunks(transmissions, line, T0))


def split_chunk(chunk: Chunk, cuts: list[int], char_time_ns: float) -> list[Chunk]:
    """The same bytes as several chunks, each stamped with the end of its own last byte."""
    positions = sorted({c for c in cuts if 0 < c < len(chunk.data)})
    bounds = [0, *positions, len(chunk.data)]
    pieces = []
    for begin, end in pairwise(bounds):
        chars_after = len(chunk.data) - end
        pieces.append(Chunk(chunk.t_end_ns - round(chars_after * char_time_ns), chunk.data[begin:end]))
    return pieces


def frames_of(chunks: list[Chunk], line: LineSettings, batch_sizes: list[int]) -> list[tuple[object, ...]]:
    framer = Framer(line)
    out = []
    position, turn = 0, 0
    while position < len(chunks):
        size = batch_sizes[turn % len(batch_sizes)]
        out.extend(framer.feed(ChunkBatch.from_chunks(chunks[position : position + size])))
        position += size
        turn += 1
    out.extend(framer.flush())
    return [(f.data, f.t_start_ns, f.t_end_ns, f.flags, f.crc_ok, f.idle_before_ns) for f in out]


@settings(max_examples=80, deadline=None)
@given(captures(), st.data())
def test_rechunking_does_not_change_frames(capture: tuple[LineSettings, list[Chunk]], data: st.DataObject) -> None:
    line, chunks = capture
    reference = frames_of(chunks, line, [len(chunks)])
    rechunked = []
    for chunk in chunks:
        cuts = data.draw(st.lists(st.integers(1, max(1, len(chunk.data) - 1)), max_size=4))
        rechunked.extend(split_chunk(chunk, cuts, line.char_time_ns))
    batch_sizes = data.draw(st.lists(st.integers(1, 5), min_size=1, max_size=4))
    result = frames_of(rechunked, line, batch_sizes)
    assert close(result, reference), (result, reference)


#: A read holds at most this much of the wire's time (a read loop returns at its timeout).
READ_SPAN_NS = 400_000_000


def deliveries(wire: list[Chunk], line: LineSettings, data: st.DataObject) -> list[Chunk]:
    """The wire's bytes cut into reads at random (none holding more than ``READ_SPAN_NS`` of
    the wire), each stamped at or after its last byte's end by up to half a second, in order:
    a read loop whose times are consistent with the wire, delivering within a second."""
    from benchmarks.read_loops import wire_byte_ends

    payload, ends = wire_byte_ends(wire, line)
    cuts = set(data.draw(st.lists(st.integers(1, max(1, len(payload) - 1)), max_size=len(payload) // 4)))
    read_start = 0
    for index in range(1, len(payload)):
        if index in cuts or ends[index] - ends[read_start] > READ_SPAN_NS:
            cuts.add(index)
            read_start = index
    bounds = [0, *sorted(c for c in cuts if 0 < c < len(payload)), len(payload)]
    reads, stamp = [], 0
    for begin, end in pairwise(bounds):
        delay = data.draw(st.sampled_from([0, 1_000_000, 16_000_000, 100_000_000, 500_000_000]))
        stamp = max(stamp, ends[end - 1] + delay)
        reads.append(Chunk(stamp, payload[begin:end]))
    return reads


@settings(max_examples=int(os.environ.get("RTUSNIFF_EXAMPLES", "100")), deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 12), LINES, st.data())
def test_host_rechunking_finds_every_frame(seed: int, exchanges: int, line: LineSettings, data: st.DataObject) -> None:
    """Real frames (pymodbus) with realistic silences, read by any read loop consistent with
    the wire: every frame is found where it was sent, and nothing else passes as a frame."""
    import random

    from decoders.capture import TimingQuality
    from tests.corpus import exchange

    rng = random.Random(seed)
    transmissions, sent, offset = [], [], 0
    for _ in range(exchanges):
        for frame in exchange(rng, rng.randint(1, 247)):
            silence = int(rng.choice([0.5, 2.0, 20.0, 200.0]) * line.t3_5_ns)
            transmissions.append(Transmission(frame, silence))
            sent.append((offset, frame))
            offset += len(frame)
    wire = list(exact_chunks(transmissions, line, T0))
    framer = Framer(line, TimingQuality.HOST)
    reads = deliveries(wire, line, data)
    frames = []
    for k in range(0, len(reads), 3):
        frames.extend(framer.feed(ChunkBatch.from_chunks(reads[k : k + 3])))
    frames.extend(framer.flush())
    found, position = [], 0
    for frame in frames:
        if frame.crc_ok and not frame.is_noise:
            found.append((position, frame.data))
        position += len(frame.data)
    assert found == sent
