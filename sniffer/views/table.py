"""The table view of ``analyze``: a frame a row, on a terminal or down a pipe.

On a terminal (:class:`TableView` with a width) the columns fit its width and long summaries
wrap at whole words (:mod:`sniffer.views.layout`). To a pipe or a file (:class:`PlainTableView`)
every frame is one line with one field per column (an empty one written ``-``) and the summary
last, so that ``grep``, ``awk`` and ``less -S`` work; the heading and closing lines start with
``#``. There everything but the summary is laid out by the sink's ``prepare`` — where frames are
paired, in the decoding process with ``--jobs 2`` — and this process only adds the summaries.
Rows are laid out a block at a time from columns, so memory does not grow with the capture.
"""

from __future__ import annotations

import itertools
import operator
from dataclasses import dataclass
from typing import TYPE_CHECKING, TextIO

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, TimingQuality
from decoders.damage import RetryDiff
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.message import MessageBatch, slice_messages
from decoders.stats import Statistics
from sniffer.sinks import Sink
from sniffer.views import fixed_width
from sniffer.views.clock import Clock
from sniffer.views.frame_cells import (
    NARROW,
    SummaryOf,
    decoding_summary,
    frame_cells,
    frame_columns,
    frame_notes,
    kept_rows,
    summary_cells,
)
from sniffer.views.layout import Layout, note_lines
from sniffer.wording import counted

if TYPE_CHECKING:
    from rich.color import ColorSystem

#: Rows laid out at once: bounds memory, and on a terminal the first rows appear at once.
ROWS_PER_BLOCK = 2000
HOST_NOTE = ("host timing: times are when the PC read the bytes (USB adapters deliver them in bursts, "
             "up to their latency timer late); frames are found from their content, and silences and "
             "latencies are between reads, not measured on the wire (no gap_1_5 / short_idle).")
ROLE_ORDER_NAMES = ["request", "response", "exception", "broadcast", "unknown", "noise"]


class _FrameTable(Sink):
    """What both tables share: the heading, the date lines, the closing count."""

    wants_messages = True
    wants_statistics = True

    def __init__(self, out: TextIO, layout: Layout, clock: Clock, summary_of: SummaryOf) -> None:
        self._out = out
        self._layout = layout
        self._clock = clock
        self._summary_of = summary_of
        self._retries = RetryDiff()
        self._day: int | None = None
        #: Frames shown so far.
        self.shown = 0

    def _note_lines(self, text: str, style: str = "") -> str:
        if self._layout.plain:
            return f"# {text}\n"
        assert self._layout.width is not None
        return "".join(self._layout.styled(line, style) + "\n" for line in note_lines(text, self._layout.width))

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._out.write(self._note_lines(f"{source}  line {line.format()}  timing {info.timing.value}  "
                                         f"t1.5 {line.t1_5_ns / 1e3:.0f} µs  t3.5 {line.t3_5_ns / 1e3:.0f} µs",
                                         "bold"))
        if info.timing is TimingQuality.HOST:
            self._out.write(self._note_lines(HOST_NOTE, "yellow"))

    def _date_cuts(self, times: npt.NDArray[np.int64]) -> list[tuple[int, int, str]]:
        """The rows cut where the date changes: ``(begin, end, the date line before begin or "")``."""
        days = self._clock.days(times)
        cuts = [0, *(np.flatnonzero(np.diff(days)) + 1).tolist(), len(times)]
        parts = []
        for begin, end in itertools.pairwise(cuts):
            if begin == end:
                continue
            line = ""
            day = int(days[begin])
            if self._clock.mode != "relative" and day != self._day:
                stamp = self._clock.date(int(times[begin]))
                words = "capture starts" if self._day is None else "date"
                line = self._note_lines(f"{words} {stamp if self._day is None else stamp[:10]} ({self._clock.zone})",
                                        "bold")
                self._day = day
            parts.append((begin, end, line))
        return parts

    def finish(self, statistics: Statistics) -> None:
        roles, flags = statistics.roles, statistics.flags
        shown = f"{self.shown} of {counted(statistics.frames, 'frame')} shown" if self.shown != statistics.frames \
            else counted(statistics.frames, "frame").replace(",", "")
        parts = [shown] + [f"{roles[r]} {r}" for r in ROLE_ORDER_NAMES if roles[r]]
        if statistics.crc_errors:
            parts.append(counted(statistics.crc_errors, "CRC error").replace(",", ""))
        parts += [f"{n} {flag}" for flag, n in sorted(flags.items())]
        self._out.write(self._note_lines(", ".join(parts)))
        hidden = self._layout.hidden() if self.shown else []
        if hidden:
            self._out.write(self._note_lines(f"(no room at {self._layout.width} columns for: {', '.join(hidden)}; "
                                             "see --width, --hex, or a pipe)", "dim"))
        self._out.flush()


class TableView(_FrameTable):
    """The table on a terminal ``width`` columns wide, in ``color_system``'s colours (``None``:
    none); rows are laid out here, with their summaries."""

    def __init__(self, out: TextIO, *, width: int, color_system: ColorSystem | None = None,
                 clock: Clock | None = None, hex_shown: bool | None = None,
                 summary_of: SummaryOf = decoding_summary) -> None:
        clock = clock or Clock()
        layout = Layout(frame_columns(clock, plain=False, hex_shown=hex_shown), width, color_system)
        super().__init__(out, layout, clock, summary_of)
        self._header_shown = False

    def messages(self, batch: AnnotatedBatch) -> None:
        frames = batch.messages.frames
        if self._clock.origin_ns is None and len(frames):  # relative times count from the window's first frame
            self._clock.origin_ns = int(frames.t_start_ns[0])
        retries = self._retries.notes(batch.messages)
        rows = kept_rows(batch)
        for start in range(0, len(rows), ROWS_PER_BLOCK):
            self._block(batch, rows[start : start + ROWS_PER_BLOCK], retries)

    def _block(self, batch: AnnotatedBatch, rows: npt.NDArray[np.int64], retries: dict[int, str]) -> None:
        width = self._layout.width
        for begin, end, date_line in self._date_cuts(batch.messages.frames.t_start_ns[rows]):
            self._out.write(date_line)
            part = rows[begin:end]
            cells = frame_cells(batch.messages, part, self._clock, plain=False,
                                styled=self._layout.color_system is not None,
                                short_roles=width is not None and width < NARROW)
            cells["summary"] = summary_cells(batch, part, self._summary_of, frame_notes(batch.messages, part, retries))
            self._layout.measure(cells)
            if not self._header_shown:
                self._out.write(self._layout.header())
                self._header_shown = True
            self._out.write(self._layout.lines(cells, end - begin, measured=True))
            self.shown += end - begin


@dataclass(frozen=True)
class PlainRows:
    """A framed batch laid out but for the summaries: per position the fields before the
    summary (padded, with the gap after them) and what follows the summary (notes, a newline);
    comment lines (the heading, dates) by the position they go before."""

    prefixes: list[str]
    suffixes: list[str]
    marks: list[tuple[int, str]]


class PlainTableView(_FrameTable):
    """The table into a pipe or a file: a line per frame. ``prepare`` lays out every frame of a
    framed batch but the summary; ``messages`` and ``prepared`` write the frames kept, each with
    its summary."""

    def __init__(self, out: TextIO, *, clock: Clock | None = None, hex_shown: bool | None = None,
                 summary_of: SummaryOf = decoding_summary, fast: bool = True) -> None:
        clock = clock or Clock()
        #: Rows laid out by numpy (:mod:`sniffer.views.fixed_width`); without the hex column only.
        self._fast = fast and not hex_shown
        super().__init__(out, Layout(frame_columns(clock, plain=True, hex_shown=bool(hex_shown)), None),
                         clock, summary_of)
        self._header_laid = False
        self._kept: AnnotatedBatch | None = None
        #: Comment lines waiting for the next frame shown.
        self._marks: list[str] = []
        self.prepare = self._lay_out

    def _lay_out(self, batch: MessageBatch) -> PlainRows:
        """Where frames are paired: every column but the summary, and the notes after it."""
        rows = np.arange(len(batch), dtype=np.int64)
        retries = self._retries.notes(batch)
        notes = frame_notes(batch, rows, retries)
        prefixes: list[str] = []
        marks: list[tuple[int, str]] = []
        for begin, end, date_line in self._date_cuts(batch.frames.t_start_ns):
            if date_line:
                marks.append((begin, date_line))
            if self._fast:
                laid = fixed_width.prefixes(self._layout, slice_messages(batch, begin, end), self._clock)
            else:
                cells = frame_cells(batch, rows[begin:end], self._clock, plain=True, styled=False)
                self._layout.measure(cells)
                laid = self._layout.plain_prefixes(cells, end - begin)
            if not self._header_laid:
                marks.append((begin, self._layout.header()))
                self._header_laid = True
            prefixes += laid
        suffixes = ["\n"] * len(batch)
        for position, note in notes.items():
            suffixes[position] = note + "\n"
        return PlainRows(prefixes, suffixes, marks)

    def messages(self, batch: AnnotatedBatch) -> None:
        self._kept = batch

    def prepared(self, value: PlainRows) -> None:
        batch, self._kept = self._kept, None
        if batch is None:
            return
        rows = batch.positions()
        if self._summary_of is decoding_summary:  # the decoded form's, not an object per frame
            summaries = batch.remarked_summaries()
        else:
            summaries = list(map(self._summary_of, batch.decodings_at(rows)))
        marks, reached = value.marks, 0
        for begin, end in _runs_between_marks(rows, [position for position, _ in marks]):
            while reached < len(marks) and marks[reached][0] <= rows[begin]:
                self._marks.append(marks[reached][1])
                reached += 1
            self._write(value, rows[begin:end], summaries[begin:end])
        self._marks += [line for _, line in marks[reached:]]

    def _write(self, value: PlainRows, rows: list[int], summaries: list[str]) -> None:
        if self._marks:
            self._out.write("".join(self._marks))
            self._marks = []
        if len(rows) == len(value.prefixes):
            prefixes, suffixes = value.prefixes, value.suffixes
        else:
            prefixes, suffixes = [value.prefixes[r] for r in rows], [value.suffixes[r] for r in rows]
        self._out.write("".join(map(operator.add, map(operator.add, prefixes, summaries), suffixes)))
        self.shown += len(rows)


def _runs_between_marks(rows: list[int], marks: list[int]) -> list[tuple[int, int]]:
    """``rows`` (positions, ascending) cut before each row that a mark's position reaches:
    ``(begin, end)`` indexes into ``rows``; none when there are no rows."""
    if not rows:
        return []
    cuts = sorted({0, len(rows), *np.searchsorted(np.array(rows, np.int64), marks, "left").tolist()})
    return [(begin, end) for begin, end in itertools.pairwise(cuts) if begin < end]
