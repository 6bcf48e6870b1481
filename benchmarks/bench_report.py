"""`rtusniff report` of growing captures: time, peak memory and the report's size; prints a table.

    python -m benchmarks.bench_report [--frames 400000 4000000 35000000] [--line "115200 8N1"]
        [--format html|md] [--keep DIR]

Each size is generated as a native MCAP capture (a saturated line of 16 drives with every fault,
values held for a while as running drives do: ``generate_capture --values steady``) and reported on
in a fresh process that prints its own peak RSS. Bounded memory means the peak does not grow with
the capture, and the report's size stops growing once the charts have all their buckets.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import generate_capture
from decoders.line import LineSettings

CHILD = """
import resource, sys, time
from sniffer.cli import main
start = time.perf_counter()
code = main(["report", *sys.argv[1:], "--quiet"])
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""


def measure(capture: Path, out: Path, kind: str) -> tuple[float, int]:
    """Seconds and peak RSS (kB) of one report, in its own process."""
    done = subprocess.run([sys.executable, "-c", CHILD, str(capture), "-o", str(out), "--format", kind, "--force"],
                          capture_output=True, text=True, check=True)
    seconds, rss = done.stdout.split()
    return float(seconds), int(rss)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, nargs="+", default=[400_000, 4_000_000])
    parser.add_argument("--line", default="115200 8N1")
    parser.add_argument("--format", choices=["html", "md"], default="html")
    parser.add_argument("--keep", type=Path, help="keep the captures and reports in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.keep or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"{'frames':>12} {'capture MB':>11} {'generated s':>12} {'report s':>9} {'frames/s':>10} "
              f"{'peak RSS MB':>12} {'report kB':>10}")
        for frames in args.frames:
            capture = folder / f"report-{frames}.mcap"
            started = time.perf_counter()
            if not capture.exists():
                generate_capture.write(capture, frames, 1, LineSettings.parse(args.line), "exact", values="steady")
            generated = time.perf_counter() - started
            out = folder / f"report-{frames}.{args.format}"
            seconds, rss_kb = measure(capture, out, args.format)
            print(f"{frames:>12,} {capture.stat().st_size / 1e6:>11.1f} {generated:>12.1f} {seconds:>9.1f} "
                  f"{frames / seconds:>10,.0f} {rss_kb / 1024:>12.1f} {out.stat().st_size / 1e3:>10.0f}", flush=True)


if __name__ == "__main__":
    main()
