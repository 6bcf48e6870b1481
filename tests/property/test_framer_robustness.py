"""Hypothesis: noise between frames loses no valid frame (exact timing, and host timing
through every read-loop model); arbitrary bytes never raise."""

from __future__ import annotations

import os
import random

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.read_loops import READ_LOOPS
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import Chunk, ChunkBatch, TimingQuality
from decoders.frame import Frame
from decoders.framer import Framer
from decoders.line import LineSettings
from tests.corpus import exchange

T0 = 1_600_000_000_000_000_000
#: RTUSNIFF_EXAMPLES raises the number of examples for a long run.
EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "150"))
LINES = st.sampled_from([LineSettings.parse(t) for t in ("9600 8E1", "19200 8E1", "115200 8N1")])


def run(chunks: list[Chunk], line: LineSettings, timing: TimingQuality, batch: int = 16) -> list[Frame]:
    framer = Framer(line, timing)
    out: list[Frame] = []
    for start in range(0, len(chunks), batch):
        out.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + batch])))
    out.extend(framer.flush())
    return out


def valid_frames_at(frames: list[Frame]) -> set[tuple[int, bytes]]:
    found, offset = set(), 0
    for frame in frames:
        if frame.crc_ok and not frame.is_noise:
            found.add((offset, frame.data))
        offset += len(frame.data)
    return found


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    line=LINES,
    seed=st.integers(0, 2**32 - 1),
    noise=st.lists(st.binary(min_size=1, max_size=12), min_size=1, max_size=8),
    host=st.booleans(),
)
def test_noise_between_frames_loses_no_valid_frame(
    line: LineSettings, seed: int, noise: list[bytes], host: bool
) -> None:
    check_noise_between_frames(line, seed, noise, host)


def test_host_noise_case_found_by_the_long_fuzz_run() -> None:
    """Found with RTUSNIFF_EXAMPLES=60000: 12 noise bytes plus the first 5 bytes of the next
    request (FC 15) passed the CRC as one frame of the unknown function 0x4A, hiding the request.
    A CRC-search candidate may no longer overlap a frame that its length rule finds."""
    noise = [b"\x00"] * 5 + [bytes.fromhex("d34ae828963fe708c9807af2")]
    check_noise_between_frames(LineSettings.parse("9600 8E1"), 66, noise, host=True)


def check_noise_between_frames(line: LineSettings, seed: int, noise: list[bytes], host: bool) -> None:
    rng = random.Random(seed)
    transmissions, sent = [], []
    offset = 0
    for i in range(10):
        request, response = exchange(rng, rng.randint(1, 247))
        for frame in (request, response):
            transmissions.append(Transmission(frame, int(rng.uniform(1.1, 4.0) * line.t3_5_ns)))
            sent.append((offset, frame))
            offset += len(frame)
        if i < len(noise):
            junk = noise[i]
            # Noise right behind the frame, inside its t3.5 window, or on its own.
            silence = int(rng.choice([0.0, 0.5, 1.5]) * line.t3_5_ns)
            transmissions.append(Transmission(junk, silence))
            offset += len(junk)
    chunks = list(exact_chunks(transmissions, line, T0))
    timing = TimingQuality.EXACT
    if host:
        chunks, timing = READ_LOOPS[rng.choice(sorted(READ_LOOPS))](chunks, line, seed), TimingQuality.HOST
    frames = run(chunks, line, timing)
    assert b"".join(f.data for f in frames) == b"".join(c.data for c in chunks)
    found = valid_frames_at(frames)
    missing = [(o, f.hex()) for o, f in sent if (o, f) not in found]
    assert not missing


@st.composite
def arbitrary_chunks(draw: st.DrawFn) -> list[Chunk]:
    t = draw(st.integers(0, 2**62))
    chunks = []
    for _ in range(draw(st.integers(0, 30))):
        t += draw(st.integers(0, 50_000_000))
        chunks.append(Chunk(t, draw(st.binary(min_size=1, max_size=300))))
    return chunks


@settings(max_examples=EXAMPLES * 2, deadline=None)
@given(chunks=arbitrary_chunks(), line=LINES, host=st.booleans(), batch=st.integers(1, 8))
def test_arbitrary_bytes_never_raise_and_every_byte_is_placed(
    chunks: list[Chunk], line: LineSettings, host: bool, batch: int
) -> None:
    frames = run(chunks, line, TimingQuality.HOST if host else TimingQuality.EXACT, batch)
    assert b"".join(f.data for f in frames) == b"".join(c.data for c in chunks)
    assert [f.index for f in frames] == list(range(len(frames)))
    for frame in frames:
        assert frame.data
        assert frame.t_start_ns <= frame.t_end_ns
        assert not (frame.is_noise and frame.crc_ok)
