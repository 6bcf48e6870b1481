"""Precision and recall of frame boundaries per line condition and read loop; prints tables.

    python -m benchmarks.framing_quality [--seeds N] [--exchanges N]

Captures come from tests/corpus.py (frames built by pymodbus, faults injected with
known ground truth) at 9600 8N1, 19200 8E1 and 115200 8N1: exact, and through
every read-loop model of benchmarks/read_loops.py (host timing). Beside rtusniff's
framer runs a timing-only splitter (a new frame after every silence >= t3.5 of the
times recorded), the naive baseline. Then the real recordings of ../shared/real/
against sigrok's own decodes, as recorded and through every read loop.

recall: valid frames found with exact boundaries / valid frames sent.
precision: of the CRC-valid frames reported, those that were sent.
spurious: CRC-valid frames reported that were never sent.
pieces: frames, damaged frames and noise runs reported exactly as sent.
paired: answers sent with a valid CRC that the matcher paired with their request (as answers:
a retry of an FC 5/6 request, which repeats its answer's bytes, paired in its place is none).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from itertools import accumulate, pairwise

import numpy as np

from benchmarks.read_loops import READ_LOOPS
from benchmarks.wire_synthesis import byte_times
from decoders.capture import ChunkBatch, TimingQuality
from decoders.crc import crc_ok
from decoders.framer import Framer
from decoders.message import Role
from decoders.pipeline import Decoder
from tests import real_recordings
from tests.corpus import LINES, SCENARIOS, Corpus, Expected, Score, build, deliver, host_expected, score

Emitted = list[tuple[bytes, bool, bool, frozenset[str]]]
TIMINGS = ["exact", *sorted(READ_LOOPS)]


def rtusniff(corpus: Corpus) -> Emitted:
    framer = Framer(corpus.line, corpus.timing)
    frames = []
    for start in range(0, len(corpus.chunks), 256):
        frames.extend(framer.feed(ChunkBatch.from_chunks(corpus.chunks[start : start + 256])))
    frames.extend(framer.flush())
    return [(f.data, f.is_noise, f.crc_ok, frozenset(f.flags.names)) for f in frames]


def timing_only(corpus: Corpus) -> Emitted:
    batch = ChunkBatch.from_chunks(corpus.chunks)
    starts, ends = byte_times(batch, corpus.line.char_time_ns)
    cuts = [0, *(np.flatnonzero(starts[1:] - ends[:-1] >= corpus.line.t3_5_ns) + 1).tolist(), len(batch.data)]
    pieces = [batch.data[a:b] for a, b in pairwise(cuts)]
    return [(p, False, crc_ok(p), frozenset()) for p in pieces]


def paired(corpus: Corpus, expected: list[Expected]) -> tuple[int, int]:
    """(answers paired with a request, valid answers sent)."""
    decoder = Decoder(corpus.line, corpus.timing)
    messages = []
    for start in range(0, len(corpus.chunks), 256):
        messages.extend(m for part in decoder.feed(ChunkBatch.from_chunks(corpus.chunks[start : start + 256]))
                        for m in part)
    messages.extend(m for part in decoder.flush() for m in part)
    # An answer counts where one was sent: a master's retry of an FC 5/6 request, byte for
    # byte its answer, taken as the answer is no answer paired.
    sent = {(at, e.data) for at, e in zip(_offsets(e.data for e in expected), expected, strict=True)
            if e.role == "response" and e.crc_ok}
    answers = sum(1 for at, m in zip(_offsets(m.frame.data for m in messages), messages, strict=True)
                  if m.role in (Role.RESPONSE, Role.EXCEPTION) and m.request_index is not None and m.frame.crc_ok
                  and (at, m.frame.data) in sent)
    return answers, len(sent)


def _offsets(pieces: Iterable[bytes]) -> list[int]:
    """Where each of consecutive ``pieces`` of the capture's bytes begins."""
    return list(accumulate((len(piece) for piece in pieces), initial=0))[:-1]


def row(name: str, timing: str, framer: str, total: Score, pairs: tuple[int, int] | None) -> str:
    pairing = f"{pairs[0] / pairs[1]:>8.2%}" if pairs and pairs[1] else f"{'':>8}"
    return (f"{name:<17} {timing:<13} {framer:<12} {total.frames:>7} {total.recall:>8.2%} "
            f"{total.precision:>9.2%} {total.spurious_valid:>8} {total.pieces_exact / total.pieces:>8.2%} {pairing}")


def corpus_table(seeds: int, exchanges: int) -> None:
    header = (f"{'case':<17} {'timing':<13} {'framer':<12} {'frames':>7} {'recall':>8} "
              f"{'precision':>9} {'spurious':>8} {'pieces':>8} {'paired':>8}")
    print(header)
    print("-" * len(header))
    totals: dict[tuple[str, str], tuple[Score, list[int]]] = {}
    for scenario in SCENARIOS:
        for timing in TIMINGS:
            for name, framer in (("rtusniff", rtusniff), ("timing-only", timing_only)):
                total, pairs = Score(), [0, 0]
                for seed in range(seeds):
                    for line in LINES:
                        corpus = build(scenario, line, exchanges=exchanges, seed=seed)
                        expected = corpus.expected
                        if timing != "exact":
                            corpus, expected = deliver(corpus, timing, seed), host_expected(expected)
                        total.add(score(expected, framer(corpus)))
                        if name == "rtusniff":
                            found, sent = paired(corpus, expected)
                            pairs[0] += found
                            pairs[1] += sent
                overall, overall_pairs = totals.setdefault((timing, name), (Score(), [0, 0]))
                overall.add(total)
                overall_pairs[0] += pairs[0]
                overall_pairs[1] += pairs[1]
                if name == "rtusniff" or timing == "exact":
                    print(row(scenario.name, timing, name, total, (pairs[0], pairs[1]) if name == "rtusniff" else None))
    print("-" * len(header))
    for (timing, name), (total, pairs) in totals.items():
        print(row("all", timing, name, total, (pairs[0], pairs[1]) if name == "rtusniff" else None))


def real_table() -> None:
    if not real_recordings.available():
        print("\n../shared/real is not beside the checkout: no real recordings")
        return
    print(f"\n{'real recording':<40} {'timing':<13} {'sigrok':>7} {'found':>7} {'spurious':>8}")
    for file_name, expected_name in sorted(real_recordings.RECORDINGS.items()):
        if expected_name is None:
            continue
        recording = real_recordings.load(file_name)
        truth = set(recording.frames or [])
        for timing in TIMINGS:
            chunks = recording.chunks if timing == "exact" else READ_LOOPS[timing](recording.chunks, recording.line, 0)
            quality = TimingQuality.EXACT if timing == "exact" else TimingQuality.HOST
            framer = Framer(recording.line, quality)
            frames = [*framer.feed(ChunkBatch.from_chunks(chunks)), *framer.flush()]
            found, offset = set(), 0
            for frame in frames:
                if frame.crc_ok and not frame.is_noise:
                    found.add((offset, offset + len(frame.data)))
                offset += len(frame.data)
            print(f"{file_name:<40} {timing:<13} {len(truth):>7} {len(found & truth):>7} {len(found - truth):>8}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--exchanges", type=int, default=300)
    args = parser.parse_args()
    corpus_table(args.seeds, args.exchanges)
    real_table()


if __name__ == "__main__":
    main()
