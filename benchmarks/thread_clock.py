"""Runs one rtusniff command and says where its CPU went, thread by thread (for ``bench_versus --threads``).

    PYTHONPATH=TREE python benchmarks/thread_clock.py COMMAND ARGS…

Prints, as the last line on standard error, JSON: ``wall`` (seconds from this script's start),
``main`` (the CPU of the thread that annotates and writes: what bounds the exports), ``writer``
(the Parquet writing thread's, where there is one), ``children`` (the decoding process's: the
children this process waited for). Run as a script with the tree to measure on ``PYTHONPATH``,
so that an earlier commit's tree is measured by this checkout's clock. The command runs as the
installed ``rtusniff`` runs it (the tree's ``entry_point``), its exit included in the wall time
``bench_versus`` takes.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

START = time.perf_counter()


def _clock_writer(clocks: dict[str, float]) -> None:
    """The Parquet writing thread's CPU, taken as it ends (a tree without one: none)."""
    try:
        from sniffer.exports import parquet_writing  # in the tree measured
    except ImportError:
        return
    run = parquet_writing.RowGroupWriter._run

    def clocked(self: Any) -> None:
        try:
            run(self)
        finally:
            clocks["writer"] = clocks.get("writer", 0.0) + time.thread_time()

    parquet_writing.RowGroupWriter._run = clocked


def main() -> None:
    """Runs the command as the installed ``rtusniff`` does (the tree's ``entry_point``, and so
    its way of exiting too), its ``main`` clocked."""
    import resource  # POSIX, as the benchmarks' machines are

    clocks: dict[str, float] = {}
    _clock_writer(clocks)
    from sniffer import cli  # in the tree measured

    command = cli.main

    def clocked(argv: Any = None) -> int:
        try:
            code: int = command(sys.argv[1:])
        finally:
            children = resource.getrusage(resource.RUSAGE_CHILDREN)
            print(json.dumps({"wall": time.perf_counter() - START, "main": time.thread_time(),
                              "writer": clocks.get("writer", 0.0),
                              "children": children.ru_utime + children.ru_stime}), file=sys.stderr)
        return code

    cli.main = clocked
    cli.entry_point()  # exits


if __name__ == "__main__":
    main()
