"""Many captures at once (``--each``): every file its own capture, several decoded at a time.

A plant's recorders leave thousands of files; ``stats --each DIR`` and ``export --each DIR
--parquet DATASET`` take them all. Each capture is decoded in a process of a pool (``--jobs N``;
one process, no pool, with ``--jobs 1``) by the command's own code for one capture, and what it
returns (``stats``: its statistics, merged exactly by :meth:`decoders.stats.Statistics.merge`)
comes back in the order the files were named. A capture that fails is one error line naming it,
and the others go on; the command then ends with :data:`SOME_FAILED`.

Directories are searched for the files a capture reader knows by their suffix (``.mcap``,
``.log``, ``.sr``, …), recursively, in name order; files named are taken as they are.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Generic, TypeVar

from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.registry import formats_for
from sniffer.progress import over_captures

if TYPE_CHECKING:
    from concurrent.futures import Future

#: The exit code of a command of which some captures failed (each said in its error line).
SOME_FAILED = 15
#: Captures handed to the pool ahead of the one being merged: memory stays bounded.
AHEAD_PER_JOB = 4

Result = TypeVar("Result")


@dataclass(frozen=True)
class Outcome(Generic[Result]):
    """One capture's result, or the error line that says why it has none."""

    path: str
    result: Result | None
    error: str | None = None


def add_each_options(parser: argparse.ArgumentParser, merged: str) -> None:
    """``--each`` and, where the command has none, ``--jobs`` (captures decoded at once)."""
    parser.add_argument("--each", action="store_true",
                        help="every file its own capture (a directory: the capture files in it), decoded --jobs at a "
                        f"time; {merged}; a capture that fails is one error line and the others go on (exit "
                        f"{SOME_FAILED})")
    if not any(action.dest == "jobs" for action in parser._actions):
        parser.add_argument("--jobs", default="auto", metavar="N|auto",
                            help="with --each: captures decoded at once (default auto: one per core)")


def capture_files(paths: list[str]) -> list[str]:
    """The files of ``paths``: each file as named, each directory's capture files in name order."""
    suffixes = _capture_suffixes()
    files: list[str] = []
    for path in paths:
        if path != "-" and os.path.isdir(path):
            inside = captures_in(path)
            if not inside:
                raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "holds no capture file "
                                    f"({', '.join(sorted(suffixes))})", path=path)
            files += inside
        elif path == "-":
            raise RtuSniffError(ErrorKind.USAGE, "--each reads files, not standard input")
        else:
            files.append(path)
    return files


def _capture_suffixes() -> set[str]:
    return {suffix for found in formats_for("read").values() for suffix in found.suffixes}


def captures_in(directory: str) -> list[str]:
    """The capture files under ``directory`` (by suffix, hidden files left out), in name order."""
    suffixes = _capture_suffixes()
    return sorted(str(found) for found in Path(directory).rglob("*")
                  if found.is_file() and found.suffix.lower() in suffixes and not found.name.startswith("."))


def jobs_for_each(requested: str) -> int:
    """``--jobs`` with ``--each``: captures decoded at once (``auto``: this process's cores)."""
    if requested == "auto":
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    try:
        jobs = int(requested)
    except ValueError:
        jobs = 0
    if jobs < 1:
        raise RtuSniffError(ErrorKind.USAGE, f"--jobs {requested}: give a number of processes (1 or more) or auto")
    return jobs


def each_capture(paths: list[str], one: Callable[[argparse.Namespace], Result], args: argparse.Namespace,
                 jobs: int) -> Iterator[Outcome[Result]]:
    """``one(args)`` for every capture, ``args.capture`` set to it, in the order of ``paths``."""
    if jobs == 1:
        for path in paths:
            yield _one(one, args, path)
        return
    # fork where there is one (start-up costs nothing); a fresh interpreter elsewhere.
    import multiprocessing  # noqa: PLC0415 - slow to import (sockets, selectors), for many captures alone
    from concurrent.futures import ProcessPoolExecutor  # noqa: PLC0415 - the same

    context = multiprocessing.get_context("fork" if hasattr(os, "fork") else "spawn")
    with ProcessPoolExecutor(jobs, mp_context=context) as pool:
        pending: list[Future[Outcome[Result]]] = []
        try:
            for path in paths:
                pending.append(pool.submit(_one, one, args, path))
                if len(pending) >= jobs * AHEAD_PER_JOB:
                    yield pending.pop(0).result()
            for future in pending:
                yield future.result()
        except BaseException:
            # Stopped (Ctrl-C, SIGTERM, a failure): the captures queued ahead are not started;
            # those under way end with their worker.
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def _one(one: Callable[[argparse.Namespace], Result], args: argparse.Namespace, path: str) -> Outcome[Result]:
    try:
        return Outcome(path, one(argparse.Namespace(**{**vars(args), "capture": [path]})))
    except RtuSniffError as exc:
        return Outcome(path, None, str(exc))


@dataclass
class Tally:
    """The captures of an ``--each`` command: how many were named, done, and failed."""

    total: int
    done: int = 0
    failed: int = 0

    def exit_code(self) -> int:
        """0, or :data:`SOME_FAILED` after saying how many captures failed (each said its error
        line as it came)."""
        if self.failed:
            print(f"{self.failed} of {self.total} captures failed", file=sys.stderr)
        return SOME_FAILED if self.failed else 0


def each_result(paths: list[str], one: Callable[[argparse.Namespace], Result], args: argparse.Namespace,
                jobs: int, tally: Tally, *, show: bool) -> Iterator[Result]:
    """``one(args)`` of every capture that succeeds, in the order of ``paths`` (with a bar over
    the captures when ``show``); a capture that fails is its error line, counted in ``tally``.
    Nothing of a result is kept once the caller has it: a report's part or a capture's statistics
    weigh megabytes, and memory stays flat over any number of captures."""
    for outcome in over_captures(each_capture(paths, one, args, jobs), paths, show):
        if outcome.result is None:
            print(f"error: {outcome.error}", file=sys.stderr, flush=True)
            tally.failed += 1
            continue
        tally.done += 1
        yield outcome.result
