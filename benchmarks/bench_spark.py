"""Decoding on Spark against ``export --each --jobs 2``: the same captures into the same dataset.

    python -m benchmarks.bench_spark [--captures 20] [--frames 50000] [--runs 2]

Generates ``--captures`` captures of ``--frames`` frames each (the ``mixed`` values of
``benchmarks.generate_capture``, 19200 8E1, exact timing), then, ``--runs`` times each, one after
the other: ``rtusniff export --each DIR --parquet OUT --jobs 2`` in its own process, and
``sniffer.spark.decode`` on a local Spark session (``local[2]``, bound to 127.0.0.1; started once,
its start timed apart; its cache emptied before each run) with every table written by Spark's
writer, partitioned by bus and date; the decoding (every capture decoded and cached) timed too.
Prints each run's seconds, frames/s, and what a year of a plant would take: 50 lines at
19 200 Bd (about 2·10**11 frames) on a cluster of 16 executors of 2 cores each, at the rate per
core measured here, of the whole job (Spark's writer included) and of its decoding alone.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import generate_capture
from decoders.line import LineSettings

ROOT = Path(__file__).resolve().parent.parent
#: A year of a plant: 50 lines at 19 200 Bd, 8E1 (11 bits a character), busy polling whose
#: frames average 10 bytes with a gap of 3.5 characters: about 130 frames/s a line, 2·10**11 a year.
PLANT_FRAMES = 50 * 365 * 86_400 * 19_200 / 11 / 13.5
#: The cluster of the arithmetic.
EXECUTORS, CORES = 16, 2


def _export(captures: Path, out: Path) -> float:
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "sniffer", "export", "--each", str(captures), "--parquet", str(out),
                    "--jobs", "2", "-q"], check=True, cwd=ROOT)
    return time.perf_counter() - start


def _spark_run(spark: Any, captures: Path, out: Path) -> tuple[float, float]:
    """The job's seconds, and of those its decoding's (every capture decoded and cached, as the
    first table read makes it). Spark's cache is emptied first: it would otherwise hand the same
    plan the decodings of the run before."""
    import sniffer
    import sniffer.spark

    shutil.rmtree(out, ignore_errors=True)
    spark.catalog.clearCache()
    start = time.perf_counter()
    tables = sniffer.spark.decode(spark, str(captures))
    assert tables["errors"].count() == 0  # decodes every capture, into the cache
    decoded = time.perf_counter()
    for name in sniffer.TABLES:
        tables[name].write.partitionBy("bus", "date").parquet(str(out / name))
    return time.perf_counter() - start, decoded - start


def _session() -> tuple[Any, float]:
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"
    os.environ["PYSPARK_PYTHON"] = sys.executable
    from pyspark.sql import SparkSession

    start = time.perf_counter()
    spark = (SparkSession.builder.master("local[2]").appName("rtusniff-bench")
             .config("spark.driver.bindAddress", "127.0.0.1").config("spark.driver.host", "127.0.0.1")
             .config("spark.ui.enabled", "false").config("spark.sql.session.timeZone", "UTC").getOrCreate())
    spark.sparkContext.setLogLevel("ERROR")
    spark.range(1).count()  # the JVM and a first job started
    return spark, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--captures", type=int, default=20)
    parser.add_argument("--frames", type=int, default=50_000)
    parser.add_argument("--runs", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch_name:
        scratch = Path(scratch_name)
        captures = scratch / "captures"
        captures.mkdir()
        for seed in range(args.captures):
            generate_capture.write(captures / f"line-{seed:02d}.mcap", args.frames, seed,
                                   LineSettings.parse("19200 8E1"), "exact", values="mixed")
        frames = args.captures * args.frames
        spark, started = _session()
        times: dict[str, list[float]] = {"export --each --jobs 2": [], "Spark local[2]": [],
                                         "  of which decoding": []}
        for _ in range(args.runs):
            times["export --each --jobs 2"].append(_export(captures, scratch / "exported"))
            whole, decoding = _spark_run(spark, captures, scratch / "spark")
            times["Spark local[2]"].append(whole)
            times["  of which decoding"].append(decoding)
        print(f"{args.captures} captures of {args.frames:,} frames ({frames:,} frames); Spark's session "
              f"started in {started:.1f} s (not counted)")
        print(f"{'how':<24} {'seconds':>20} {'frames/s (median)':>18}")
        for how, found in times.items():
            median = statistics.median(found)
            print(f"{how:<24} {' '.join(f'{t:.1f}' for t in found):>20} {frames / median:>18,.0f}")
        print(f"a year of 50 lines at 19 200 Bd: {PLANT_FRAMES:.2e} frames; on {EXECUTORS} executors of {CORES} cores, "
              "at the rate per core measured here:")
        for how in ("Spark local[2]", "  of which decoding"):
            per_core = frames / statistics.median(times[how]) / 2
            days = PLANT_FRAMES / (per_core * EXECUTORS * CORES) / 86_400
            print(f"  {how.strip():<18} {per_core:>8,.0f} frames/s a core: {days:.1f} days "
                  f"({PLANT_FRAMES / (per_core * 86_400):,.0f} core-days)")


if __name__ == "__main__":
    main()
