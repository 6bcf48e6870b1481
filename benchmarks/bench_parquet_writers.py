"""What writing the Parquet tables costs, and whether another writer would cost less; prints tables.

    python -m benchmarks.bench_parquet_writers [--frames 1000000] [--traffic coils] [--keep DIR] [--columns]

The capture is exported once (``rtusniff export --parquet``); each table is then read back and
written again, in this one process, by each writer that is installed:

* ``rtusniff``: pyarrow through ``RowGroupWriter``, with the export's own settings (dictionaries,
  differences, statistics, row groups of ``ROW_GROUP_ROWS``);
* ``pyarrow plain``: pyarrow's defaults but zstd (no dictionaries, no statistics);
* ``polars``: ``DataFrame.write_parquet`` (zstd, no statistics), when polars is installed;
* ``duckdb``: ``COPY … (FORMAT parquet)`` (zstd) on one thread, when duckdb is installed.

CPU seconds count every thread of the process (polars writes on both cores); each figure is the
best of ``--rounds``. ``--columns`` also writes each column of each table alone with the export's
settings: where the writing thread's time goes.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from benchmarks.bench_memory import add_capture_options, benchmark_capture
from sniffer.exports.parquet_export import (
    DELTA_COLUMNS,
    DICTIONARY_COLUMNS,
    DICTIONARY_PAGE_BYTES,
    ROW_GROUP_ROWS,
    UNSUMMARISED_COLUMNS,
)
from sniffer.exports.parquet_writing import RowGroupWriter

Writer = Callable[[str, pa.Table, Path], None]


def write_as_exported(name: str, table: pa.Table, path: Path) -> None:
    """The export's own writer and settings, a row group per ``ROW_GROUP_ROWS`` rows."""
    writer = RowGroupWriter(DICTIONARY_COLUMNS, DELTA_COLUMNS, UNSUMMARISED_COLUMNS, DICTIONARY_PAGE_BYTES)
    for start in range(0, table.num_rows, ROW_GROUP_ROWS):
        writer.write(path, name, table.slice(start, ROW_GROUP_ROWS))
    writer.close()


def write_plain(name: str, table: pa.Table, path: Path) -> None:
    pq.write_table(table, path, compression="zstd", use_dictionary=False, write_statistics=False,
                   row_group_size=ROW_GROUP_ROWS)


def write_polars(name: str, table: pa.Table, path: Path) -> None:
    import polars  # optional: measured only when installed

    frame = polars.from_arrow(table)
    assert isinstance(frame, polars.DataFrame)
    frame.write_parquet(path, compression="zstd", statistics=False, row_group_size=ROW_GROUP_ROWS)


def write_duckdb(name: str, table: pa.Table, path: Path) -> None:
    import duckdb  # optional: measured only when installed

    connection = duckdb.connect()
    connection.execute("SET threads = 1")
    connection.register("rows", table)
    connection.execute(f"COPY rows TO '{path}' (FORMAT parquet, COMPRESSION zstd, ROW_GROUP_SIZE {ROW_GROUP_ROWS})")
    connection.close()


WRITERS: dict[str, tuple[Writer, str | None]] = {
    "rtusniff": (write_as_exported, None),
    "pyarrow plain": (write_plain, None),
    "polars": (write_polars, "polars"),
    "duckdb": (write_duckdb, "duckdb"),
}


def measured(write: Writer, name: str, table: pa.Table, path: Path, rounds: int) -> tuple[float, float, int]:
    """Best wall and CPU seconds of ``rounds`` writes, and the file's size in bytes."""
    wall = cpu = float("inf")
    for _ in range(rounds):
        path.unlink(missing_ok=True)
        cpu_start, wall_start = time.process_time(), time.perf_counter()
        write(name, table, path)
        wall = min(wall, time.perf_counter() - wall_start)
        cpu = min(cpu, time.process_time() - cpu_start)
    return wall, cpu, path.stat().st_size


def exported_tables(capture: Path, folder: Path) -> dict[str, pa.Table]:
    """The capture's Parquet tables, as ``rtusniff export`` writes them, without their partition columns."""
    subprocess.run([sys.executable, "-m", "sniffer", "export", str(capture), "--parquet", str(folder), "-q"],
                   check=True)
    tables = {}
    for name in ("frames", "transactions", "values"):
        (file,) = folder.glob(f"{name}/*/*/*.parquet")
        tables[name] = pq.read_table(file, partitioning=None).replace_schema_metadata(None)
    return tables


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--columns", action="store_true", help="also each column alone, with the export's settings")
    add_capture_options(parser)
    parser.set_defaults(traffic="coils")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        capture = benchmark_capture(args.keep or Path(tmp), args.frames, args.traffic)
        tables = exported_tables(capture, Path(tmp) / "dataset")
        output = Path(tmp) / "rewritten.parquet"
        print(f"{args.traffic}, {args.frames:,} frames; best of {args.rounds}")
        print(f"{'table':<13} {'rows':>11} {'writer':<14} {'wall s':>7} {'CPU s':>7} {'MB':>7}")
        for name, table in tables.items():
            for writer, (write, module) in WRITERS.items():
                if module is not None and importlib.util.find_spec(module) is None:
                    print(f"{name:<13} {table.num_rows:>11,} {writer:<14} not installed (pip install {module})")
                    continue
                wall, cpu, size = measured(write, name, table, output, args.rounds)
                print(f"{name:<13} {table.num_rows:>11,} {writer:<14} {wall:>7.3f} {cpu:>7.3f} {size / 1e6:>7.1f}")
        if args.columns:
            print(f"\n{'table':<13} {'column':<15} {'CPU s':>7} {'MB':>7}  type")
            for name, table in tables.items():
                for column in table.schema.names:
                    _, cpu, size = measured(write_as_exported, name, table.select([column]), output, args.rounds)
                    print(f"{name:<13} {column:<15} {cpu:>7.3f} {size / 1e6:>7.2f}  {table.schema.field(column).type}")


if __name__ == "__main__":
    main()
