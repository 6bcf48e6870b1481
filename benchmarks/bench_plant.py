"""A plant's recordings into one Parquet dataset, and a query over it; prints a table.

    python -m benchmarks.bench_plant [--captures 10 40] [--frames 20000] [--lines 40] [--jobs 2]
                                     [--traffic mixed] [--no-report]

Many captures of one kind (``--frames`` each), the recordings of a plant as the issue has it:
``--lines`` RS485 lines, a recorder on each writing a file an hour (capture *k* is hour
``k // lines`` of line ``k % lines``, its bus the line, its times those of one capture moved on by
the hour; ``--lines`` as many as the captures: every capture its own bus, one hour each, the worst
case for the queries, which then group as many buses as files). They are exported with
``export --each FOLDER --parquet DATASET --jobs N`` in a fresh process: wall time, frames/s, the
peak RSS of the parent and of the largest worker (memory must not grow with the number of
captures), the dataset's size; then the README's DuckDB queries (latency p95 per slave per day
across all buses, exact over ``transactions`` and to within 1 % over ``latencies``: "bins"),
timed over the dataset (the median of three runs); then ``report --each FOLDER --jobs N`` of the
same captures into one HTML report: wall time and peak RSS of it and its pool (``--no-report``:
not made, for the largest plants, where it would take as long again).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import TRAFFICS, benchmark_capture, compile_sources
from decoders.capture import ChunkBatch
from sniffer.io.registry import open_reader, open_writer

HOUR_NS = 3_600 * 1_000_000_000

#: Runs the command given as its arguments and prints its peak RSS (KiB) with that of its pool.
_MEASURED = ("import resource, subprocess, sys; code = subprocess.call(sys.argv[1:]); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(code)")


def measured(command: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS in MB of ``command`` and every process it waited for."""
    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-c", _MEASURED, *command], capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if result.returncode != 0:
        sys.exit(f"bench_plant: {' '.join(command[2:4])} failed: {result.stderr}")
    return seconds, int(result.stdout.split()[-1]) / 1024


QUERY = """
SELECT bus, date, slave, count(*) AS answers, quantile_cont(latency_ms, 0.95) AS latency_p95_ms
FROM read_parquet('{dataset}/transactions/*/*/*.parquet', hive_partitioning = true)
WHERE outcome = 'answered' GROUP BY ALL ORDER BY bus, date, slave
"""
#: The same question over the latency histograms (to within 1 %), as the README has it.
HISTOGRAM_QUERY = """
WITH bins AS (
  SELECT bus, date, slave, to_ms, sum(answers) AS answers
  FROM read_parquet('{dataset}/latencies/*/*/*.parquet', hive_partitioning = true)
  GROUP BY bus, date, slave, to_ms),
running AS (
  SELECT *, sum(answers) OVER (PARTITION BY bus, date, slave ORDER BY to_ms) AS up_to,
            sum(answers) OVER (PARTITION BY bus, date, slave) AS total
  FROM bins)
SELECT bus, date, slave, max(total) AS answers,
       min(to_ms) FILTER (WHERE up_to >= 0.95 * total) AS latency_p95_ms
FROM running GROUP BY bus, date, slave ORDER BY bus, date, slave
"""


def queried(query: str, runs: int = 3) -> float:
    """The median wall time of ``query``, each run in a connection of its own (nothing cached)."""
    import duckdb

    seconds = []
    for _ in range(runs):
        connection = duckdb.connect()
        start = time.perf_counter()
        connection.sql(query).fetchall()
        seconds.append(time.perf_counter() - start)
        connection.close()
    return sorted(seconds)[runs // 2]


def moved_on(source: Path, target: Path, by_ns: int) -> None:
    """``source`` written again at ``target`` with every time ``by_ns`` later (another hour)."""
    reader = open_reader(str(source))
    writer = open_writer(str(target), reader.info)
    try:
        for batch in reader.batches():
            writer.write_batch(ChunkBatch(batch.data, batch.ends, batch.t_end_ns + by_ns, batch.uart_errors,
                                          batch.channels))
    finally:
        writer.close()
        reader.close()


def plant(folder: Path, one: Path, captures: int, lines: int) -> None:
    """``captures`` recordings in ``folder``: ``hour-HHH/line-LL.mcap``, so that each one's bus
    (the file's name) is its line."""
    for number in range(captures):
        hour, line = divmod(number, lines)
        hour_folder = folder / f"hour-{hour:03d}"
        hour_folder.mkdir(exist_ok=True)
        recording = hour_folder / f"line-{line:04d}.mcap"
        if line == 0:
            moved_on(one, recording, hour * HOUR_NS)
        else:
            shutil.copy(hour_folder / "line-0000.mcap", recording)  # the same traffic on another line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--captures", type=int, nargs="+", default=[10, 40])
    parser.add_argument("--frames", type=int, default=20_000)
    parser.add_argument("--lines", type=int, default=40, help="the plant's lines, each recorded a file an hour")
    parser.add_argument("--jobs", default="2")
    parser.add_argument("--traffic", default="mixed", choices=TRAFFICS)
    parser.add_argument("--no-report", action="store_true", help="export and query only")
    args = parser.parse_args()
    compile_sources()

    print(f"{'captures':>8} {'buses':>5} {'frames':>10} {'export s':>9} {'frames/s':>9} {'peak RSS MB':>12} "
          f"{'dataset MB':>11} {'query s':>8} {'bins s':>8} {'report s':>9} {'frames/s':>9} {'peak RSS MB':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        one = benchmark_capture(Path(tmp) / "one", args.frames, args.traffic)
        for count in args.captures:
            folder, dataset = Path(tmp) / f"plant-{count}", Path(tmp) / f"dataset-{count}"
            folder.mkdir()
            plant(folder, one, count, args.lines)
            before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            start = time.perf_counter()
            result = subprocess.run([sys.executable, "-m", "sniffer", "export", "--each", str(folder), "--parquet",
                                     str(dataset), "--jobs", args.jobs, "-q"], capture_output=True, text=True,
                                    check=False)
            seconds = time.perf_counter() - start
            if result.returncode != 0:
                sys.exit(f"bench_plant: export failed: {result.stderr}")
            worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
            size = sum(path.stat().st_size for path in dataset.rglob("*.parquet")) / 1e6
            query, histogram_query = (queried(text.format(dataset=dataset)) for text in (QUERY, HISTOGRAM_QUERY))
            frames = count * args.frames
            exported = (f"{count:>8} {min(count, args.lines):>5} {frames:>10,} {seconds:>9.1f} "
                        f"{frames / seconds:>9,.0f} {max(worker, before) / 1024:>12.0f} {size:>11.1f} "
                        f"{query:>8.3f} {histogram_query:>8.3f}")
            if args.no_report:
                print(exported, flush=True)
                shutil.rmtree(dataset)
                shutil.rmtree(folder)
                continue
            report, report_rss = measured([sys.executable, "-m", "sniffer", "report", "--each", str(folder), "-o",
                                           str(Path(tmp) / f"report-{count}.html"), "--jobs", args.jobs, "-q"])
            print(f"{exported} {report:>9.1f} {frames / report:>9,.0f} {report_rss:>12.0f}", flush=True)


if __name__ == "__main__":
    main()
