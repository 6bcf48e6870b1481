"""The table view of ``analyze``: a frame a row, on a terminal or down a pipe.

On a terminal the columns fit its width and long summaries wrap at whole words
(:mod:`sniffer.views.layout`); to a pipe or a file every frame is one line with one
field per column (an empty one written ``-``) and the summary last, so that ``grep``,
``awk`` and ``less -S`` work; the heading and footing lines there start with ``#``.
Rows are laid out a block at a time from columns, so memory does not grow with the capture.
"""

from __future__ import annotations

import itertools
import textwrap
from typing import TextIO

import numpy as np
from rich.color import ColorSystem

from decoders.capture import CaptureInfo, TimingQuality
from decoders.damage import RetryDiff
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch
from decoders.stats import Statistics
from sniffer.sinks import Sink
from sniffer.views.clock import Clock
from sniffer.views.frame_cells import NARROW, SummaryOf, decoding_summary, frame_cells, frame_columns
from sniffer.views.layout import Layout

#: Rows laid out at once: bounds memory, and on a terminal the first rows appear at once.
ROWS_PER_BLOCK = 2000
HOST_NOTE = ("host timing: times are when the PC read the bytes (USB adapters deliver them in bursts, "
             "up to their latency timer late); frames are found from their content, and silences and "
             "latencies are between reads, not measured on the wire (no gap_1_5 / short_idle).")


class TableView(Sink):
    """Prints a heading, the frames a block at a time, and a closing count.

    ``width``: the terminal's (``None``: plain lines for a pipe or a file); ``color_system``:
    the terminal's colours, ``None`` for none."""

    wants_messages = True
    wants_statistics = True

    def __init__(self, out: TextIO, *, width: int | None, color_system: ColorSystem | None = None,
                 clock: Clock | None = None, hex_shown: bool | None = None,
                 summary_of: SummaryOf = decoding_summary) -> None:
        self._out = out
        self._clock = clock or Clock()
        plain = width is None
        self._layout = Layout(frame_columns(self._clock, plain=plain, hex_shown=None if hex_shown is None and not plain
                                            else bool(hex_shown)), width, color_system)
        self._summary_of = summary_of
        self._retries = RetryDiff()
        self._header_shown = False
        self._day: int | None = None
        self.shown = 0

    @property
    def _plain(self) -> bool:
        return self._layout.plain

    def _note(self, text: str, style: str = "") -> None:
        if self._plain:
            self._out.write(f"# {text}\n")
            return
        assert self._layout.width is not None
        for line in textwrap.wrap(text, self._layout.width, break_on_hyphens=False):
            self._out.write(self._layout.styled(line, style) + "\n")

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._note(f"{source}  line {line.format()}  timing {info.timing.value}  "
                   f"t1.5 {line.t1_5_ns / 1e3:.0f} µs  t3.5 {line.t3_5_ns / 1e3:.0f} µs", "bold")
        if info.timing is TimingQuality.HOST:
            self._note(HOST_NOTE, "yellow")

    def messages(self, batch: AnnotatedBatch) -> None:
        notes = self._retries.notes(batch.messages)
        if not len(batch):
            return
        rows = np.arange(len(batch.decodings), dtype=np.int64) if batch.rows is None else batch.rows
        for start in range(0, len(rows), ROWS_PER_BLOCK):
            self._block(batch, rows[start : start + ROWS_PER_BLOCK], notes)

    def _block(self, batch: AnnotatedBatch, rows: np.ndarray, notes: dict[int, str]) -> None:
        times = batch.messages.frames.t_start_ns[rows]
        days = self._clock.days(times)
        # Cut the block where the date changes: the new date goes on a line of its own.
        cuts = [0, *(np.flatnonzero(np.diff(days)) + 1).tolist(), len(rows)]
        for begin, end in itertools.pairwise(cuts):
            if begin == end:
                continue
            day = int(days[begin])
            if self._clock.mode != "relative" and day != self._day:
                stamp = self._clock.date(int(times[begin]))
                words = "capture starts" if self._day is None else "date"
                self._note(f"{words} {stamp if self._day is None else stamp[:10]} ({self._clock.zone})", "bold")
                self._day = day
            part = AnnotatedBatch(batch.messages, batch.decodings, rows[begin:end])
            cells = frame_cells(part, self._clock, plain=self._plain, summary_of=self._summary_of, notes=notes,
                                styled=self._layout.color_system is not None,
                                short_roles=self._layout.width is not None and self._layout.width < NARROW)
            self._layout.measure(cells)
            if not self._header_shown:
                self._out.write(self._layout.header())
                self._header_shown = True
            self._out.write(self._layout.lines(cells, end - begin, measured=True))
            self.shown += end - begin

    def finish(self, statistics: Statistics) -> None:
        roles, flags = statistics.roles, statistics.flags
        order = ["request", "response", "exception", "broadcast", "unknown", "noise"]
        shown = f"{self.shown} of {statistics.frames} frames shown" if self.shown != statistics.frames \
            else f"{statistics.frames} frames"
        parts = [shown] + [f"{roles[r]} {r}" for r in order if roles[r]]
        if statistics.crc_errors:
            parts.append(f"{statistics.crc_errors} CRC errors")
        parts += [f"{n} {flag}" for flag, n in sorted(flags.items())]
        self._note(", ".join(parts))
        hidden = self._layout.hidden() if self.shown else []
        if hidden:
            self._note(f"(no room at {self._layout.width} columns for: {', '.join(hidden)}; "
                       "see --width, --hex, or a pipe)", "dim")
        self._out.flush()
