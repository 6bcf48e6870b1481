"""A progress bar on standard error for long commands, when standard error is a terminal.

Progress is measured in capture time: how far the frames decoded so far reach between the
first frame and the capture's end (``CaptureReader.last_time_ns``, from the file's tail or
index). It shows the share of the file that is (about) done, frames per second, the time
elapsed and the time left; where the end is unknown (standard input), a count and a rate.
The bar is a sink (it gets the framed batches, before annotation) and vanishes when the last
batch is in, before any sink writes what it kept for the end (a table of statistics), leaving
the closing line that says what was written. A command that writes its output to standard
output as it goes (``analyze``, ``values``, ``convert -``, ``export --pcap -``) shows no bar:
whatever reads that output (the terminal itself, or ``less``, ``head`` or ``grep`` through a
pipe) draws on the same terminal as the bar, and the two would overwrite each other.

Many captures at once (``--each``) get a bar over the captures instead (:func:`over_captures`):
captures done, megabytes of them, the time elapsed and left.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Iterator
from types import TracebackType
from typing import TYPE_CHECKING, Any, TypeVar

from decoders.capture import ChunkBatch
from decoders.message import MessageBatch
from decoders.stats import Statistics
from sniffer.io.base import CaptureReader
from sniffer.sinks import Sink

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

#: The bar counts in thousandths of the capture's span.
STEPS = 1000

Item = TypeVar("Item")


class ProgressSink(Sink):
    """Moves a rich progress bar as framed batches go by."""

    wants_frames = True

    def __init__(self, progress: Progress | None, task: TaskID | None, end_ns: int | None,
                 size: int | None) -> None:
        """Put it first among a command's sinks: its :meth:`finish` clears the bar before the
        others write what they kept for the end."""
        self._progress, self._task, self._end_ns, self._size = progress, task, end_ns, size
        self._first_ns: int | None = None
        self._started = time.monotonic()
        self.frame_count = 0

    def frames(self, batch: MessageBatch) -> None:
        if len(batch):
            self.advance(int(batch.frames.t_start_ns[0]), int(batch.frames.t_end_ns[-1]), len(batch))

    def finish(self, statistics: Statistics) -> None:
        if self._progress is not None:
            self._progress.stop()  # transient: the bar's lines are erased

    def chunks(self, batch: ChunkBatch) -> None:
        """For commands that copy chunks (``convert``): progress in chunks."""
        if len(batch):
            self.advance(int(batch.t_end_ns[0]), int(batch.t_end_ns[-1]), len(batch), unit="chunks")

    def advance(self, first_ns: int, reached: int, count: int, unit: str = "frames") -> None:
        """``count`` more frames (or chunks) decoded, the last ending at ``reached``."""
        self.frame_count += count
        if self._progress is None or self._task is None:
            return
        if self._first_ns is None:
            self._first_ns = first_ns
        done = None
        if self._end_ns is not None and self._end_ns > self._first_ns:
            done = min(STEPS, round(STEPS * (reached - self._first_ns) / (self._end_ns - self._first_ns)))
        elapsed = time.monotonic() - self._started
        rate = f"{self.frame_count / elapsed:,.0f} {unit}/s" if elapsed > 0 else ""
        self._progress.update(self._task, completed=done if done is not None else self.frame_count,
                              frames=f"{self.frame_count:,} {unit}", size=self._size_text(done), rate=rate)

    def _size_text(self, done: int | None) -> str:
        if self._size is None or done is None:
            return ""
        return f"≈ {self._size * done / STEPS / 1e6:,.1f} of {self._size / 1e6:,.1f} MB"


class ProgressBar:
    """A context: the bar while the command runs (or nothing), and its :attr:`sink`."""

    def __init__(self, reader: CaptureReader | None, paths: list[str], show: bool) -> None:
        self._progress: Progress | None = None
        task = end_ns = size = None
        if show and reader is not None:
            end_ns = reader.last_time_ns()
            files = [path for path in paths if path != "-" and os.path.isfile(path)]
            size = sum(map(os.path.getsize, files)) if len(files) == len(paths) else None
            from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal
            from rich.progress import (  # noqa: PLC0415
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            console = Console(file=sys.stderr)
            # Below 120 columns the size read and the rate give way: the rest stays whole.
            wide = console.width >= WIDE_PROGRESS
            columns = [_name_column(), BarColumn(bar_width=16 if wide else 10),
                       TextColumn("{task.percentage:>3.0f} %") if end_ns else MofNCompleteColumn(),
                       *([TextColumn("{task.fields[size]}")] if wide else []),
                       TextColumn("{task.fields[frames]}", table_column=_whole()),
                       *([TextColumn("{task.fields[rate]}")] if wide else []), TimeElapsedColumn(table_column=_whole())]
            if end_ns:
                columns.append(TimeRemainingColumn(table_column=_whole()))
            self._progress = Progress(*columns, console=console, transient=True)
            name = os.path.basename(paths[0]) + (f" + {len(paths) - 1}" if len(paths) > 1 else "")
            task = self._progress.add_task(name, total=STEPS if end_ns else None,
                                           frames="", size="", rate="")
        self.sink = ProgressSink(self._progress, task, end_ns, size)

    def __enter__(self) -> ProgressBar:
        if self._progress is not None:
            self._progress.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        if self._progress is not None:
            self._progress.stop()


def progress_for(args: argparse.Namespace, reader: CaptureReader, *, streaming: bool,
                 path: str | None = None) -> ProgressBar:
    """The bar for a command reading ``path`` (else the files of ``args.capture``), if
    :func:`shown`."""
    return ProgressBar(reader, [path] if path else list(args.capture), shown(args, streaming=streaming))


def shown(args: argparse.Namespace, *, streaming: bool) -> bool:
    """Whether a bar is shown: standard error is a terminal, ``--quiet`` is not given, and the
    command does not write its output to standard output as it goes (``streaming``; see the
    module's docstring)."""
    return sys.stderr.isatty() and not getattr(args, "quiet", False) and not streaming


def over_captures(outcomes: Iterator[Item], paths: list[str], show: bool) -> Iterator[Item]:
    """``outcomes`` (one per path, in order) passed on, with a bar over the captures while they
    come (``--each``); error lines printed meanwhile appear above it."""
    if not show:
        yield from outcomes
        return
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn  # noqa: PLC0415

    sizes = [os.path.getsize(path) if os.path.isfile(path) else 0 for path in paths]
    total = sum(sizes)
    progress = Progress(_name_column(), BarColumn(bar_width=16), TextColumn("{task.percentage:>3.0f} %"),
                        TextColumn("{task.fields[size]}"), TimeElapsedColumn(table_column=_whole()),
                        TimeRemainingColumn(table_column=_whole()),
                        console=Console(file=sys.stderr), transient=True)
    task = progress.add_task(f"0 of {len(paths):,} captures", total=total or len(paths), size="")
    read = 0
    with progress:
        for done, (outcome, size) in enumerate(zip(outcomes, sizes, strict=True), 1):
            read += size
            progress.update(task, completed=read if total else done, description=f"{done:,} of {len(paths):,} "
                            "captures", size=f"{read / 1e6:,.1f} of {total / 1e6:,.1f} MB")
            yield outcome


#: The terminal width from which a progress line shows the size read and the rate too.
WIDE_PROGRESS = 120


def _whole() -> Any:
    """A column that is never squeezed: a time cut to ``0:0…`` says nothing (rich shrinks the
    columns of a progress line that does not fit; the name gives way instead)."""
    from rich.table import Column  # noqa: PLC0415 - rich: only for a terminal

    return Column(no_wrap=True, min_width=7)


def _name_column() -> Any:
    """The capture's name: what gives way on a narrow terminal (cut with an ellipsis)."""
    from rich.progress import TextColumn  # noqa: PLC0415 - rich: only for a terminal
    from rich.table import Column  # noqa: PLC0415

    return TextColumn("{task.description}", table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis",
                                                                min_width=6))
