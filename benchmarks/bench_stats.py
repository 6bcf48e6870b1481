"""`rtusniff stats` end to end on large captures: frames/s and peak RSS; prints a table.

    python -m benchmarks.bench_stats [--frames 1000000 5000000] [--keep DIR] [--traffic polling|mixed|steady|coils|wide]

Captures are FC 3 polling at 115200 8N1 (32 slaves, 1 % of frames with a pause
inside), written as native MCAP captures in pieces; each size is analysed in a
fresh process that reports its own peak RSS. One core: the process is single
threaded.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_memory import add_capture_options, benchmark_capture

CHILD = """
import resource, sys, time
from sniffer.cli import main
start = time.perf_counter()
code = main(["stats", sys.argv[1], "--format", "json", "-o", sys.argv[2], "--force"])
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[1_000_000, 5_000_000])
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


if __name__ == "__main__":
    main()
