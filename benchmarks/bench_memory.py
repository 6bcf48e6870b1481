"""Peak memory of `rtusniff analyze --format jsonl` as the capture grows; prints a table.

    python benchmarks/bench_memory.py [--frames 100000 400000 1600000]

Each size is written as a native MCAP capture (generated in pieces, so the
generator's own memory stays small) and analysed in a fresh process, which
reports its own peak RSS. Streaming means the peak does not grow with the capture.
"""

from __future__ import annotations

import argparse
import compileall
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from benchmarks import generate_capture
from benchmarks.bench_framing import (
    LINE,
    coil_transmissions,
    meter_transmissions,
    polling_transmissions,
    wide_transmissions,
)
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from sniffer.io.registry import open_reader, open_writer

CHILD = """
import resource, sys, time
from sniffer.cli import main
start = time.perf_counter()
code = main(["analyze", sys.argv[1], "--format", "jsonl", "-o", "/dev/null"])
print(time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
sys.exit(code)
"""
PIECE_FRAMES = 100_000


def compile_sources() -> None:
    """Byte-compile the project, as installing its wheel does: where PYTHONDONTWRITEBYTECODE is
    set (these machines), every command would otherwise compile each module as it starts."""
    root = Path(__file__).resolve().parents[1]
    for package in ("sniffer", "decoders"):
        compileall.compile_dir(root / package, quiet=1)


#: The benchmark traffics :func:`benchmark_capture` writes.
TRAFFICS = ["polling", "mixed", "steady", "coils", "wide", "meters"]


def add_capture_options(parser: argparse.ArgumentParser) -> None:
    """``--keep`` and ``--traffic``, as every end-to-end benchmark takes them."""
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated captures in this folder")
    parser.add_argument("--traffic", choices=TRAFFICS, default="polling",
                        help="FC 3 polling of random registers and values; mixed ATV traffic with faults and random "
                             "values; the same with steady drives (benchmarks/generate_capture.py); coil reads and "
                             "writes of random states; wide: reads of 247 slaves by FC 1 to 4 (1 000 pairs of slave "
                             "and function); meters: reads of IEEE 754 floats in register pairs")


def benchmark_capture(folder: Path, frames: int, traffic: str = "polling") -> Path:
    """The benchmark capture of ``frames`` frames in ``folder``, written unless it is there:
    ``polling`` (FC 3 only), ``mixed`` or ``steady`` (benchmarks/generate_capture.py, seed 1), ``coils``,
    ``wide`` (:func:`benchmarks.bench_framing.wide_transmissions`), ``meters``
    (:func:`benchmarks.bench_framing.meter_transmissions`)."""
    folder.mkdir(parents=True, exist_ok=True)
    capture = folder / f"{traffic}-{frames}.mcap"
    if not capture.exists():
        if traffic in ("mixed", "steady"):
            values = "steady" if traffic == "steady" else "random"
            generate_capture.write(capture, frames, 1, LINE, "exact", values=values)
        else:
            traffics = {"coils": coil_transmissions, "wide": wide_transmissions, "meters": meter_transmissions}
            write_capture(capture, frames, traffics.get(traffic, polling_transmissions))
    return capture


def wire_megabytes(capture: Path) -> float:
    """The bytes on the wire the capture holds, in MB (what a throughput in MB/s counts)."""
    reader = open_reader(str(capture))
    try:
        return sum(len(batch.data) for batch in reader.batches()) / 1e6
    finally:
        reader.close()


def write_capture(path: Path, frames: int,
                  traffic: Callable[[int, int], list[Transmission]] = polling_transmissions) -> None:
    writer = open_writer(str(path), CaptureInfo(LINE, TimingQuality.EXACT))
    t0 = 1_700_000_000_000_000_000
    for piece in range(0, frames, PIECE_FRAMES):
        chunks = list(exact_chunks(traffic(min(PIECE_FRAMES, frames - piece), piece), LINE, t0))
        writer.write_batch(ChunkBatch.from_chunks(chunks))
        t0 = chunks[-1].t_end_ns + 10_000_000
    writer.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, nargs="+", default=[100_000, 400_000, 1_600_000])
    args = parser.parse_args()
    print(f"{'frames':>10} {'MB':>7} {'analyze s':>10} {'frames/s':>10} {'peak RSS MB':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for frames in args.frames:
            path = Path(tmp) / f"{frames}.mcap"
            write_capture(path, frames)
            command = [sys.executable, "-c", CHILD, str(path)]
            result = subprocess.run(command, capture_output=True, text=True, check=True)
            seconds, rss_kb = result.stdout.split()
            size_mb = path.stat().st_size / 1e6
            print(f"{frames:>10,} {size_mb:>7.1f} {float(seconds):>10.2f} {frames / float(seconds):>10,.0f} "
                  f"{int(rss_kb) / 1024:>12.1f}")


if __name__ == "__main__":
    main()
