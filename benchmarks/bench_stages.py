"""What bounds `analyze --format jsonl`: each stage added in turn, per kind of traffic; prints a table.

    python -m benchmarks.bench_stages [--frames 200000] [--keep DIR]

Three captures of the same size (benchmarks/bench_memory.py): ``steady`` drives that hold their
state and speed (what a running plant sends: the same frames again and again), ``mixed`` ATV
traffic whose values are drawn anew for every answer, and ``polling`` of random registers with
random values (no two frames alike: the worst case). Stages, one process, one core:

1. read the MCAP capture, frame, pair, count statistics (all in columns);
2. + annotate: decode each distinct frame once (a Python object per distinct frame);
3. + JSONL: the frame records, written from columns and per-decoding parts.

The ``distinct`` column is the share of frames the annotator had to decode: the rest were
repeats answered from its cache. Per-frame Python work on the distinct ones is what bounds
the throughput.
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import benchmark_capture
from decoders.message import MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier
from decoders.stats import Statistics
from sniffer.cli import GC_YOUNG_THRESHOLD
from sniffer.io.registry import open_reader
from sniffer.profiles_io import profile_book
from sniffer.views.records import FrameRecordEncoder

STAGES = ("read, frame, pair, statistics", "+ annotate", "+ JSONL records")
TRAFFIC = ("steady", "mixed", "polling")


class _CountingAnnotator(Annotator):
    """Counts the frames it decodes (the distinct ones)."""

    decoded = 0

    def _decode(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        self.decoded += 1
        return super()._decode(*args, **kwargs)


def run(capture: Path, stages: int) -> tuple[float, int, int]:
    """Seconds for the first ``stages`` stages, frames, and frames decoded."""
    reader = open_reader(str(capture))
    assert reader.info.line is not None
    decoder = Decoder(reader.info.line, reader.info.timing)
    annotator = _CountingAnnotator(ProfileApplier(profile_book([], [])))
    encoder, statistics, frames = FrameRecordEncoder(), Statistics(), 0
    start = time.perf_counter()

    def deliver(batches: list[MessageBatch]) -> None:
        nonlocal frames
        for batch in batches:
            statistics.add_batch(batch)
            frames += len(batch)
            if stages >= 2:
                annotated = annotator.annotate_batch(batch)
                if stages >= 3:
                    "\n".join(encoder.encode_batch(annotated))

    for chunks in reader.batches():
        deliver(decoder.feed(chunks))
    deliver(decoder.flush())
    return time.perf_counter() - start, frames, annotator.decoded


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated captures in this folder")
    args = parser.parse_args()
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    with tempfile.TemporaryDirectory() as tmp:
        captures = {traffic: benchmark_capture(args.keep or Path(tmp), args.frames, traffic) for traffic in TRAFFIC}
        print(f"frames/s, {args.frames:,} frames per capture")
        print(f"{'stage':<32}" + "".join(f"{traffic:>12}" for traffic in TRAFFIC))
        distinct = {}
        for stage in range(1, len(STAGES) + 1):
            row = []
            for traffic in TRAFFIC:
                seconds, frames, decoded = run(captures[traffic], stage)
                row.append(f"{frames / seconds:>12,.0f}")
                if stage == len(STAGES):
                    distinct[traffic] = decoded / frames
            print(f"{STAGES[stage - 1]:<32}" + "".join(row))
        print(f"{'distinct (decoded) frames':<32}" + "".join(f"{distinct[t]:>12.1%}" for t in TRAFFIC))


if __name__ == "__main__":
    main()
