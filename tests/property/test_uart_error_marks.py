"""Hypothesis: UART error marks and channels travel with their bytes — through chunks and
batches (split, sliced, joined), and through the framer (fast and plain paths), whatever the
chunking; bytes of two channels never share a frame."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.capture import Chunk, ChunkBatch
from decoders.framer import Framer
from decoders.line import LineSettings
from tests.property.test_framer_properties import captures

KINDS = st.sampled_from([1, 2, 3])


@st.composite
def marked(draw: st.DrawFn) -> tuple[LineSettings, list[Chunk]]:
    """A capture of valid frames and silences, some of its bytes marked, some glitch bytes
    with a framing error added between frames."""
    line, chunks = draw(captures())
    out = []
    for chunk in chunks:
        positions = draw(st.lists(st.integers(0, len(chunk.data) - 1), max_size=2, unique=True))
        marks = tuple(sorted((p, draw(KINDS)) for p in positions))
        channel = draw(st.integers(0, 2))
        if draw(st.booleans()):  # a glitch character just before the chunk, framing error
            out.append(Chunk(chunk.t_end_ns - round(len(chunk.data) * line.char_time_ns) - 1,
                             bytes([draw(st.integers(0, 255))]), ((0, 1),), channel))
        out.append(Chunk(chunk.t_end_ns, chunk.data, marks, channel))
    return line, sorted(out, key=lambda c: c.t_end_ns)


def stream_marks(chunks: list[Chunk]) -> list[tuple[int, int]]:
    marks, offset = [], 0
    for chunk in chunks:
        marks += [(offset + position, kind) for position, kind in chunk.uart_errors]
        offset += len(chunk.data)
    return marks


@settings(max_examples=150, deadline=None)
@given(marked(), st.data())
def test_batches_keep_marks_with_their_bytes(capture: tuple[LineSettings, list[Chunk]], data: st.DataObject) -> None:
    _, chunks = capture
    batch = ChunkBatch.from_chunks(chunks)
    assert list(batch.chunks()) == chunks
    cut = data.draw(st.integers(0, len(batch)))
    pieces = [batch.slice(0, cut), batch.slice(cut, len(batch))]
    assert list(ChunkBatch.concat(pieces).chunks()) == chunks
    assert [c for piece in pieces for c in piece.chunks()] == chunks


@settings(max_examples=150, deadline=None)
@given(marked(), st.data(), st.booleans())
def test_frames_hold_every_mark_at_its_byte(capture: tuple[LineSettings, list[Chunk]], data: st.DataObject,
                                            fast: bool) -> None:
    line, chunks = capture
    framer = Framer(line, fast=fast)
    size = data.draw(st.integers(1, 6))
    frames = []
    for start in range(0, len(chunks), size):
        frames.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + size])))
    frames.extend(framer.flush())
    found, offset, channels = [], 0, []
    for frame in frames:
        found += [(offset + position, kind) for position, kind in frame.uart_errors]
        assert bool(frame.uart_errors) == ("uart_error" in frame.flags.names)
        offset += len(frame.data)
        channels += [frame.channel] * len(frame.data)
    assert found == stream_marks(chunks)
    # Each frame's bytes came from its channel (so none holds bytes of two).
    assert channels == [c.channel for c in chunks for _ in c.data]


@settings(max_examples=100, deadline=None)
@given(marked())
def test_fast_and_plain_framers_agree_with_marks(capture: tuple[LineSettings, list[Chunk]]) -> None:
    line, chunks = capture
    results = []
    for fast in (True, False):
        framer = Framer(line, fast=fast)
        frames = [*framer.feed(ChunkBatch.from_chunks(chunks)), *framer.flush()]
        results.append([(f.data, f.is_noise, f.crc_ok, f.flags, f.uart_errors, f.channel) for f in frames])
    assert results[0] == results[1]
