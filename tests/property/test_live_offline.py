"""Hypothesis: a live capture and the decoding of its recording give the same records (issue 66).

The live path (``sniffer/live_capture.py``) feeds the decoder what each drain of the port's reads
brings and ticks it with the moment every read before it was decoded; at the end the recorder
writes that moment as a chunk without bytes. The offline path decodes the recording. Here both
run over real buses (../shared/real) and the shipped host sample, re-delivered as the host read
loops a live reader meets deliver them, with drains of random sizes, ticks at random moments and
stops at random delays: every frame's role, pairing and flags come out the same.

The rule both follow (``decoders/pipeline.py``): a request is timed out once the line has been
heard past its deadline, by a later frame or by the clock; time counts only up to the bytes the
framer still holds (they may be the answer); a recording's last chunk without bytes says until
when the line was heard; a request still open at the end of what was heard has no verdict.
"""

from __future__ import annotations

import os
from functools import cache

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.read_loops import READ_LOOPS
from decoders.capture import Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from sniffer.io.registry import open_reader
from tests import real_recordings
from tests.conftest import ROOT

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "25"))
#: The read loops a live reader meets: rtusniff's own (in-waiting) behind USB adapters, and reads
#: of any size (a read timeout of its own, of 500 ms, splits frames across reads no live
#: reader leaves open that long).
LOOPS = ["in-waiting", "usb-1ms", "usb-16ms", "random-sizes"]
Record = tuple[int, int, int, int]


@cache
def sources() -> list[tuple[str, LineSettings, tuple[Chunk, ...]]]:
    found = []
    reader = open_reader(str(ROOT / "captures" / "atv71-plc-poll-usb.log"))
    assert reader.info.line is not None
    found.append(("atv71-plc-poll-usb", reader.info.line, tuple(c for b in reader.batches() for c in b.chunks())))
    reader.close()
    if real_recordings.available():
        for name in real_recordings.RECORDINGS:
            recording = real_recordings.load(name)
            found.append((name, recording.line, tuple(recording.chunks)))
    return found


def _records(batches: list[MessageBatch]) -> list[Record]:
    rows = []
    for batch in batches:
        for position in range(len(batch)):
            rows.append((batch.frames.first_index + position, int(batch.role[position]),
                         int(batch.request_index[position]), int(batch.flags[position])))
    return sorted(rows)


def offline(chunks: list[Chunk], line: LineSettings) -> list[Record]:
    decoder = Decoder(line, TimingQuality.HOST)
    decoded = [batch for start in range(0, len(chunks), 64)
               for batch in decoder.feed(ChunkBatch.from_chunks(chunks[start : start + 64]))]
    return _records([*decoded, *decoder.flush()])


def live(chunks: list[Chunk], line: LineSettings, drains: list[int], step_ns: int, stop_ns: int) -> list[Record]:
    """Drains of ``drains[k]`` reads each, ticked every ``step_ns`` until the next read comes."""
    decoder = Decoder(line, TimingQuality.HOST)
    decoded: list[MessageBatch] = []
    at, turn = 0, 0
    while at < len(chunks):
        taken = chunks[at : at + drains[turn % len(drains)]]
        at, turn = at + len(taken), turn + 1
        decoded += decoder.feed(ChunkBatch.from_chunks(taken))
        now, following = taken[-1].t_end_ns, (chunks[at].t_end_ns if at < len(chunks) else stop_ns + 1)
        while now < following:
            decoded += decoder.tick(now)
            now += step_ns
    decoded += decoder.tick(stop_ns)
    return _records([*decoded, *decoder.flush()])


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(which=st.integers(0, 99), loop=st.sampled_from(LOOPS), seed=st.integers(0, 9),
       drains=st.lists(st.integers(1, 8), min_size=1, max_size=16), step_ms=st.integers(5, 300),
       stop_after_ms=st.integers(0, 5000))
def test_live_and_offline_give_the_same_records(which: int, loop: str, seed: int, *, drains: list[int],
                                                step_ms: int, stop_after_ms: int) -> None:
    _, line, recorded = sources()[which % len(sources())]
    chunks = READ_LOOPS[loop](list(recorded), line, seed)
    stop_ns = chunks[-1].t_end_ns + stop_after_ms * 1_000_000
    with_end = [*chunks, Chunk(stop_ns, b"")]  # what the recorder writes at the end
    assert live(chunks, line, drains, step_ms * 1_000_000, stop_ns) == offline(with_end, line)
