"""Export throughput: `rtusniff export --mcap` and `--rrd` on a large capture; prints a table.

    python -m benchmarks.bench_exports [--frames 1000000] [--keep DIR] [--traffic T] [--jobs 1 2]

The capture is FC 3 polling at 115200 8N1 (benchmarks/bench_stats.py); each export runs in a
fresh process that reports its own time and peak RSS.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_memory import add_capture_options, benchmark_capture, wire_megabytes

CHILD = """
import resource, sys, time
from sniffer.cli import main
start = time.perf_counter()
code = main(["export", sys.argv[1], sys.argv[2], sys.argv[3], "--force", "--jobs", sys.argv[4]])
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
      resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.exit(code)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--jobs", nargs="+", choices=["1", "2"], default=["1", "2"],
                        help="decoding processes to compare, each export run once per value (default: 1 2)")
    add_capture_options(parser)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        capture = benchmark_capture(args.keep or Path(tmp), args.frames, args.traffic)
        wire_mb = wire_megabytes(capture)
        print(f"{'export':<8} {'jobs':>4} {'frames':>10} {'seconds':>8} {'frames/s':>10} {'wire MB/s':>10} "
              f"{'output MB':>10} {'peak RSS MB':>12} {'child RSS MB':>12}")
        for option, suffix in (("--mcap", ".mcap"), ("--rrd", ".rrd")):
            for jobs in args.jobs:
                output = Path(tmp) / f"export{suffix}"
                result = subprocess.run([sys.executable, "-c", CHILD, str(capture), option, str(output), jobs],
                                        capture_output=True, text=True, check=True, env={**os.environ, "CI": "1"})
                seconds, rss_kb, child_kb = (float(field) for field in result.stdout.split())
                child = f"{child_kb / 1024:>12.1f}" if jobs == "2" else f"{'-':>12}"
                print(f"{option[2:]:<8} {jobs:>4} {args.frames:>10,} {seconds:>8.1f} {args.frames / seconds:>10,.0f} "
                      f"{wire_mb / seconds:>10.2f} {output.stat().st_size / 1e6:>10.1f} {rss_kb / 1024:>12.1f} {child}")


if __name__ == "__main__":
    main()
