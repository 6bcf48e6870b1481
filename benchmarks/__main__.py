"""The headline benchmarks in one command; each prints its table.

    python -m benchmarks [--frames 1000000] [--keep DIR]

For each kind of traffic (steady, mixed, polling, coils): ``bench_tshark`` (stats, analyze,
export --pcap, --mcap, --parquet and tshark on the same frames) and ``bench_exports`` (MCAP,
Rerun); then ``bench_stages`` (what bounds analyze, on a fifth of the frames), ``bench_stats``
on the frames and five times as many (growth of time and memory), and ``bench_views`` (the
tables' own cost). About 20 minutes at 1 M frames on the machines here.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

TRAFFIC = ("steady", "mixed", "polling", "coils")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated captures in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        keep = ["--keep", str(args.keep or tmp)]
        frames = ["--frames", str(args.frames)]
        runs = [[name, *frames, *keep, "--traffic", traffic]
                for traffic in TRAFFIC for name in ("bench_tshark", "bench_exports")]
        runs.append(["bench_stages", "--frames", str(max(args.frames // 5, 1000)), *keep])
        runs.append(["bench_stats", "--frames", str(args.frames), str(5 * args.frames), *keep])
        runs.append(["bench_views", "--frames", str(max(args.frames // 5, 1000)), *keep])
        for name, *options in runs:
            print(f"\n## python -m benchmarks.{name} {' '.join(options)}", flush=True)
            subprocess.run([sys.executable, "-m", f"benchmarks.{name}", *options], check=True)


if __name__ == "__main__":
    main()
