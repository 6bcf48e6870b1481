"""Floats against words: the same capture decoded as register pairs (``f32``) and as 16-bit words.

    python -m benchmarks.bench_value_types [--frames 500000] [--runs 3] [--keep DIR]

The capture is the ``meters`` benchmark traffic (:func:`benchmarks.bench_framing.meter_transmissions`:
32 meters answering IEEE 754 floats in register pairs, every value new). Each command runs on it
with ``--registers f32`` and with ``--registers u16``, one after the other, ``--runs`` times, each
in its own process, output to a scratch folder: ``values`` (CSV) and ``export --parquet``. The
table gives every run's seconds and the ratio of the medians (f32 / u16: below 1.10 is the
target, a float costing no more than its two words). The float run writes half the values.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import benchmark_capture

ROOT = Path(__file__).resolve().parent.parent


def _argv(command: str, capture: Path, kind: str, out: Path) -> list[str]:
    if command == "values":
        return ["values", str(capture), "--registers", kind, "-o", str(out / f"{kind}.csv"), "-q"]
    return ["export", str(capture), "--registers", kind, "--parquet", str(out / f"{kind}.parquet"), "-q"]


def _seconds(argv: list[str], out: Path) -> float:
    """One run in its own process; the scratch folder emptied first (outputs are never replaced)."""
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "sniffer", *argv], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500_000)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated capture in this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch_name:
        scratch = Path(scratch_name)
        capture = benchmark_capture(args.keep or scratch, args.frames, "meters")
        print(f"{args.frames:,} frames of meters answering floats ({capture.name})")
        print(f"{'command':<8} {'f32 (s)':>24} {'u16 (s)':>24} {'f32/u16':>8}")
        for command in ("values", "parquet"):
            times: dict[str, list[float]] = {"f32": [], "u16": []}
            for _ in range(args.runs):
                for kind in ("f32", "u16"):
                    times[kind].append(_seconds(_argv(command, capture, kind, scratch / "out"), scratch / "out"))
            shown = {kind: " ".join(f"{t:.2f}" for t in found) for kind, found in times.items()}
            ratio = statistics.median(times["f32"]) / statistics.median(times["u16"])
            print(f"{command:<8} {shown['f32']:>24} {shown['u16']:>24} {ratio:>8.2f}")


if __name__ == "__main__":
    main()
