"""Hypothesis: frames of user-defined function codes (65–72, 100–110: no length rule, as battery
management systems and vendors' devices use them), mixed with FC 3 polls, are found whole,
exact or through every read loop a PC records with (benchmarks/read_loops.py): a CRC-valid frame
of a legal address beats noise whether or not its function has a length rule (issue 66)."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.read_loops import READ_LOOPS
from decoders.capture import Chunk, ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.framer import Framer
from decoders.line import LineSettings

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "25"))
T0 = 1_700_000_000_000_000_000
LINE = LineSettings.parse("9600 8N1")
CHAR_NS = round(LINE.t3_5_ns / 3.5)  # one character on the wire
USER_DEFINED = [*range(65, 73), *range(100, 111)]


@st.composite
def exchanges(draw: st.DrawFn) -> list[bytes]:
    """Requests and answers of one master and up to 8 units, in order."""
    frames = []
    for _ in range(draw(st.integers(1, 30))):
        unit = draw(st.integers(1, 247))
        if draw(st.integers(0, 3)) == 0:  # an FC 3 poll and its answer
            count = draw(st.integers(1, 20))
            frames += [bytes([unit, 3, 0, 0, 0, count]), bytes([unit, 3, 2 * count]) + bytes(2 * count)]
            continue
        function = draw(st.sampled_from(USER_DEFINED))
        frames += [bytes([unit, function]) + draw(st.binary(max_size=draw(st.integers(0, 40))))
                   for _ in range(2)]
    return [frame + crc_bytes(frame) for frame in frames]


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(frames=exchanges(), gaps=st.lists(st.integers(3, 40), min_size=60, max_size=60),
       loop=st.sampled_from(["exact", *sorted(READ_LOOPS)]), seed=st.integers(0, 9))
def test_user_defined_frames_are_found_whole(frames: list[bytes], gaps: list[int], loop: str, seed: int) -> None:
    chunks, t = [], T0
    for position, frame in enumerate(frames):
        t += len(frame) * CHAR_NS
        chunks.append(Chunk(t, frame))
        t += gaps[position % len(gaps)] * 1_000_000
    delivered = chunks if loop == "exact" else READ_LOOPS[loop](chunks, LINE, seed)
    framer = Framer(LINE, TimingQuality.EXACT if loop == "exact" else TimingQuality.HOST)
    found = [*framer.feed(ChunkBatch.from_chunks(delivered)), *framer.flush()]
    assert [(f.data, f.crc_ok, f.is_noise) for f in found] == [(frame, True, False) for frame in frames]
