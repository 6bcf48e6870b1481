"""`rtusniff stats` end to end on large captures: frames/s and peak RSS; prints a table.

    python -m benchmarks.bench_stats [--frames 1000000 5000000] [--keep DIR] [--traffic polling|mixed|steady|coils|wide]
        [--stages [--repeat N]]

Captures are FC 3 polling at 115200 8N1 (32 slaves, 1 % of frames with a pause
inside), written as native MCAP captures in pieces; each size is analysed in a
fresh process that reports its own peak RSS. One core: the process is single
threaded. ``--stages`` also splits the time of each size into its stages, in one process:
reading the capture, framing, pairing and counting (the batches decoded once, or the best of
``--repeat`` times, then counted five times: the best of them), start-up left out.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import add_capture_options, benchmark_capture
from decoders.capture import ChunkBatch, TimingQuality, joined_batches
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from decoders.stats import Statistics
from sniffer.allocator import keep_freed_memory
from sniffer.io.registry import open_reader
from sniffer.pipeline import COUNTING_BATCH_BYTES, COUNTING_BATCH_CHUNKS

CHILD = """
import resource, sys, time
from sniffer.cli import main
start = time.perf_counter()
code = main(["stats", sys.argv[1], "--format", "json", "-o", sys.argv[2], "--force"])
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""


def stages(path: Path, repeat: int = 1) -> str:
    """Seconds of reading, framing, pairing and counting ``path``, in this process (framing and
    pairing: the best of ``repeat`` passes, each with a new decoder); the allocator tuned as
    the command line tunes it."""
    keep_freed_memory()
    start = time.perf_counter()
    reader = open_reader(str(path))
    # Joined as `stats` joins them.
    batches = list(joined_batches(reader.batches(), COUNTING_BATCH_CHUNKS, COUNTING_BATCH_BYTES))
    read = time.perf_counter() - start
    framing = pairing = float("inf")
    line = reader.info.line
    assert line is not None  # the benchmark captures say their line
    for _ in range(repeat):
        messages, (framed_s, paired_s) = _decoded(line, reader.info.timing, batches)
        framing, pairing = min(framing, framed_s), min(pairing, paired_s)
    counting = float("inf")
    for _ in range(5):
        start = time.perf_counter()
        statistics = Statistics()
        for message in messages:
            statistics.add_batch(message)
        assert statistics.per_function is not None
        counting = min(counting, time.perf_counter() - start)
    return f"read {read:.3f} s, frame {framing:.3f} s, pair {pairing:.3f} s, count {counting:.3f} s"


def _decoded(line: LineSettings, timing: TimingQuality, batches: list[ChunkBatch]
             ) -> tuple[list[MessageBatch], tuple[float, float]]:
    """The message batches of ``batches``, and the seconds framing and pairing took."""
    decoder = Decoder(line, timing)
    framing = pairing = 0.0
    messages: list[MessageBatch] = []
    for batch in batches:
        start = time.perf_counter()
        frames = decoder.framer.feed(batch)
        framed = time.perf_counter()
        messages.append(decoder.matcher.feed(frames))
        framing, pairing = framing + framed - start, pairing + time.perf_counter() - framed
    messages.extend(decoder.flush())
    return messages, (framing, pairing)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[1_000_000, 5_000_000])
    parser.add_argument("--stages", action="store_true", help="also split each size's time into its stages")
    parser.add_argument("--repeat", type=int, default=1, help="with --stages: frame and pair this many times, "
                        "print the best")
    add_capture_options(parser)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        report = Path(tmp) / "stats.json"
        print(f"{'frames':>10} {'MB':>7} {'stats s':>8} {'frames/s':>10} {'MB/s':>6} {'peak RSS MB':>12}")
        for frames in args.frames:
            path = benchmark_capture(folder, frames, args.traffic)
            command = [sys.executable, "-c", CHILD, str(path), str(report)]
            seconds, rss_kb = subprocess.run(command, capture_output=True, text=True, check=True).stdout.split()
            wire_mb = json.loads(report.read_text())["bytes"] / 1e6
            print(f"{frames:>10,} {path.stat().st_size / 1e6:>7.1f} {float(seconds):>8.2f} "
                  f"{frames / float(seconds):>10,.0f} {wire_mb / float(seconds):>6.1f} {int(rss_kb) / 1024:>12.1f}")
            if args.stages:
                print(f"{'':>10} {stages(path, args.repeat)}")


if __name__ == "__main__":
    main()
