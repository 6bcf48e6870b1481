"""Precision and recall of frame boundaries per line condition; prints a table.

    python -m benchmarks.framing_quality [--seeds N] [--exchanges N]

Captures come from tests/corpus.py (frames built by pymodbus, faults injected with
known ground truth), exact and through a USB-adapter model (62-byte buffer, latency
timer 1 and 16 ms). Beside rtusniff's framer runs a timing-only splitter (a new frame
after every silence >= t3.5), the naive baseline.

recall: valid frames found with exact boundaries / valid frames sent.
precision: of the CRC-valid frames reported, those that were sent.
spurious: CRC-valid frames reported that were never sent.
pieces: frames, damaged frames and noise runs reported exactly as sent.
"""

from __future__ import annotations

import argparse
from itertools import pairwise

import numpy as np

from decoders.byte_times import byte_times
from decoders.capture import ChunkBatch
from decoders.crc import crc_ok
from decoders.framer import Framer
from tests.corpus import LINES, SCENARIOS, Corpus, Score, build, host_expected, score, usb_adapter

Emitted = list[tuple[bytes, bool, bool, frozenset[str]]]


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--exchanges", type=int, default=300)
    args = parser.parse_args()
    header = (
        f"{'case':<17} {'timing':<10} {'framer':<12} {'frames':>7} {'recall':>8} "
        f"{'precision':>9} {'spurious':>8} {'pieces':>8}"
    )
    print(header)
    print("-" * len(header))
    totals: dict[tuple[str, str], Score] = {}
    for scenario in SCENARIOS:
        for timing in ("exact", "host 1ms", "host 16ms"):
            for name, framer in (("rtusniff", rtusniff), ("timing-only", timing_only)):
                total = Score()
                for seed in range(args.seeds):
                    for line in LINES:
                        corpus = build(scenario, line, exchanges=args.exchanges, seed=seed)
                        expected = corpus.expected
                        if timing != "exact":
                            corpus = usb_adapter(corpus, latency_ms=1.0 if timing == "host 1ms" else 16.0, seed=seed)
                            expected = host_expected(expected)
                        total.add(score(expected, framer(corpus)))
                totals.setdefault((timing, name), Score()).add(total)
                print(
                    f"{scenario.name:<17} {timing:<10} {name:<12} {total.frames:>7} {total.recall:>8.2%} "
                    f"{total.precision:>9.2%} {total.spurious_valid:>8} {total.pieces_exact / total.pieces:>8.2%}"
                )
    print("-" * len(header))
    for (timing, name), total in totals.items():
        print(
            f"{'all':<17} {timing:<10} {name:<12} {total.frames:>7} {total.recall:>8.2%} "
            f"{total.precision:>9.2%} {total.spurious_valid:>8} {total.pieces_exact / total.pieces:>8.2%}"
        )


if __name__ == "__main__":
    main()
