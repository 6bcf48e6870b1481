"""Real buses recorded by other people: every frame sigrok decoded with a correct CRC is
found whole and none is invented, as recorded (exact timing) and re-delivered through
every read-loop model (host timing), by the fast path and by the reference."""

from __future__ import annotations

import itertools

import pytest

from benchmarks.read_loops import READ_LOOPS
from decoders.capture import Chunk, ChunkBatch, TimingQuality
from decoders.framer import Framer
from decoders.line import LineSettings
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier
from sniffer.profiles_io import profile_book
from tests import real_recordings
from tests.oracles import AnewApplier, PlainAnnotator
from tests.property.test_annotation_cache import said
from tests.real_recordings import RECORDINGS, Recording, load

pytestmark = pytest.mark.skipif(not real_recordings.available(), reason="../shared/real is not beside the checkout")


def valid_frames(
    chunks: list[Chunk], line: LineSettings, timing: TimingQuality, *, fast: bool = True, batch: int = 7
) -> list[tuple[int, int]]:
    """(first byte, end) of every CRC-valid frame the framer reports; every byte placed once."""
    framer = Framer(line, timing, fast=fast)
    frames = []
    for start in range(0, len(chunks), batch):
        frames.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + batch])))
    frames.extend(framer.flush())
    assert b"".join(f.data for f in frames) == b"".join(c.data for c in chunks)
    found, offset = [], 0
    for frame in frames:
        if frame.crc_ok and not frame.is_noise:
            found.append((offset, offset + len(frame.data)))
        offset += len(frame.data)
    return found


@pytest.fixture(scope="module", params=sorted(RECORDINGS))
def recording(request: pytest.FixtureRequest) -> Recording:
    return load(request.param)


def truth(recording: Recording) -> list[tuple[int, int]]:
    """sigrok's frames; for the one recording sigrok-test has no decode of, the exact framing."""
    if recording.frames is not None:
        return recording.frames
    return valid_frames(recording.chunks, recording.line, TimingQuality.EXACT)


def test_exact_recording_gives_sigrok_frames(recording: Recording) -> None:
    found = valid_frames(recording.chunks, recording.line, TimingQuality.EXACT)
    assert found == truth(recording)
    assert valid_frames(recording.chunks, recording.line, TimingQuality.EXACT, fast=False) == found


@pytest.mark.parametrize("read_loop", sorted(READ_LOOPS))
@pytest.mark.parametrize("seed", [0, 1])
def test_recording_through_a_read_loop(recording: Recording, read_loop: str, seed: int) -> None:
    delivered = READ_LOOPS[read_loop](recording.chunks, recording.line, seed)
    assert b"".join(c.data for c in delivered) == recording.data
    found = valid_frames(delivered, recording.line, TimingQuality.HOST)
    assert found == truth(recording)
    if seed == 0:
        assert valid_frames(delivered, recording.line, TimingQuality.HOST, fast=False) == found


def test_recording_with_a_glitch_after_every_frame_and_no_silence(recording: Recording) -> None:
    """The recording's frames back to back, each followed by a stray 0x00 or 0xFE: no t3.5
    anywhere, and the frames are still all found, on exact and on host timing."""
    from benchmarks.wire_synthesis import Transmission, exact_chunks

    data = recording.data
    frames = truth(recording)
    transmissions = []
    expected, offset = [], 0
    for k, (first, end) in enumerate(frames):
        frame = data[first:end]
        transmissions.append(Transmission(frame, int(2 * recording.line.char_time_ns)))
        expected.append((offset, offset + len(frame)))
        stray = b"\x00" if k % 2 == 0 else b"\xfe"
        transmissions.append(Transmission(stray, 0))
        offset += len(frame) + 1
    chunks = list(exact_chunks(transmissions, recording.line, 1_700_000_000_000_000_000))
    assert valid_frames(chunks, recording.line, TimingQuality.EXACT) == expected
    for read_loop in ("random-sizes", "read-timeout"):
        delivered = READ_LOOPS[read_loop](chunks, recording.line, 0)
        assert valid_frames(delivered, recording.line, TimingQuality.HOST) == expected


def test_host_frames_last_their_length_on_the_wire(recording: Recording) -> None:
    """A frame that two reads delivered still lasted its length in characters: host times
    place it ending with its last byte, so durations and bus load stay physical."""
    delivered = READ_LOOPS["read-timeout"](recording.chunks, recording.line, 0)
    framer = Framer(recording.line, TimingQuality.HOST)
    frames = [*framer.feed(ChunkBatch.from_chunks(delivered)), *framer.flush()]
    for frame in frames:
        if not frame.is_noise:
            assert frame.t_end_ns - frame.t_start_ns == round(len(frame.data) * recording.line.char_time_ns)
    read_ends = set(itertools.accumulate(len(c.data) for c in delivered))
    offsets = list(itertools.accumulate(len(f.data) for f in frames))
    straddling = [f for f, end in zip(frames, offsets, strict=True)
                  if any(end - len(f.data) < e < end for e in read_ends)]
    assert straddling  # 32-byte reads end inside frames: the case this is about


@pytest.mark.parametrize("profiles", [None, ["atv71"], ["xbt"]])
def test_decodings_shortcuts_say_what_the_plain_path_says(recording: Recording, profiles: list[str] | None) -> None:
    """The annotator's shortcuts (the memo, frames decoded from their values by their shape, the
    kept namers) on real traffic, against decoding every frame alone by the plain path: a
    flowmeter's readings change from answer to answer, and a profile for all names its registers."""
    decoder = Decoder(recording.line, TimingQuality.EXACT)
    batches = [*decoder.feed(ChunkBatch.from_chunks(recording.chunks)), *decoder.flush()]
    book = None if profiles is None else profile_book(profiles, [])
    cached = Annotator(None if book is None else ProfileApplier(book))
    plain = PlainAnnotator(None if profiles is None else AnewApplier(profile_book(profiles, [])))
    got = [said(m.decoding) for batch in batches for m in cached.annotate_batch(batch)]
    assert got == [said(plain.annotate(m).decoding) for batch in batches for m in batch]
    assert len(got) > 10
