"""The live terminal view of ``capture``: redrawn a few times a second, as tall and as wide as
the terminal: the status, the slaves, and as many of the latest frames as fit below (with
their latency), laid out by the same rules as ``analyze`` (:mod:`sniffer.views.layout`)."""

from __future__ import annotations

import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field

import numpy as np
from rich.console import Console, ConsoleOptions, RenderResult
from rich.text import Text

from decoders.decoded_batch import AnnotatedBatch
from decoders.findings import diagnose
from decoders.message import ROLE_CODE, MessageBatch, Role
from decoders.stats import Histogram, Statistics
from decoders.symptoms import Symptoms
from sniffer.sinks import Sink
from sniffer.views.clock import Clock
from sniffer.views.frame_cells import (
    NARROW,
    decoding_summary,
    frame_cells,
    frame_columns,
    kept_rows,
    summary_cells,
)
from sniffer.views.layout import ALWAYS, Cells, Column, Layout, terminal_colors
from sniffer.wording import counted

#: Frames kept for the view: more than any terminal is tall.
KEPT_FRAMES = 300
SLAVE_COLUMNS = [
    Column("slave", "slave", right=True),
    Column("requests", "requests", right=True),
    Column("responses", "responses", right=True),
    Column("exceptions", "exc", right=True, keep=40),
    Column("crc", "CRC err", right=True),
    Column("timeouts", "timeouts", right=True),
    Column("p50", "lat p50 ms", right=True, keep=30),
    Column("p95", "lat p95 ms", right=True, keep=20),
    Column("fill", "", flexible=True, min_width=0, keep=ALWAYS),
]
_REQUEST = ROLE_CODE[Role.REQUEST]
#: Slaves listed before "… and N more".
SHOWN_SLAVES = 8
#: Findings shown in the status, most severe first.
SHOWN_FINDINGS = 3


@dataclass
class LiveState:
    """What the capture knows besides the decoded traffic."""

    port: str
    line: str
    recording: str | None
    timing_note: str
    advice: str | None = None
    behind_reads: int = 0
    recorded_bytes: int = 0
    uart_errors: str | None = None
    #: Where the live viewers' streams go, and what they skipped.
    streams: str | None = None
    started: float = field(default_factory=time.monotonic)


class LiveView(Sink):
    """Keeps the latest frames; :meth:`render` gives what the terminal shows now."""

    wants_messages = True
    wants_statistics = True

    def __init__(self, state: LiveState, clock: Clock | None = None) -> None:
        self.state = state
        self.clock = clock or Clock()
        self._recent: deque[tuple[AnnotatedBatch, list[str]]] = deque()
        self._kept = 0
        #: End times of recent requests by frame index, for the latency of their answers.
        self._requests: OrderedDict[int, int] = OrderedDict()
        #: Per slave, the latencies between host read times of its answers (the ``~`` figures):
        #: what the slaves' table shows where the timing measures none on the wire.
        self.read_latency: dict[int, Histogram] = {}
        #: The findings' evidence (host times: the rules of silences and stray bytes do not apply).
        self.evidence = Symptoms(0, exact=False)

    def messages(self, batch: AnnotatedBatch) -> None:
        if not len(batch):
            return
        self.evidence.add(batch.messages)
        self.evidence.add_decoded(batch)
        rows = np.arange(len(batch.decoded), dtype=np.int64) if batch.rows is None else batch.rows
        latencies = self._read_latencies(batch.messages)
        rows = rows[-KEPT_FRAMES:]
        kept = np.zeros(len(batch.messages), np.bool_)
        kept[rows] = True
        self._recent.append((batch.select(kept),
                             [latencies[row] for row in rows.tolist()]))
        self._kept += len(rows)
        while self._kept - len(self._recent[0][0]) >= KEPT_FRAMES:
            self._kept -= len(self._recent.popleft()[0])

    def _read_latencies(self, messages: MessageBatch) -> list[str]:
        """Each answer's latency between host read times (``~``: not measured on the wire; a
        live tap reads a port, and the decoder publishes no host latency), by position."""
        frames, first = messages.frames, messages.frames.first_index
        texts = [""] * len(messages)
        answered, slaves = messages.request_index.tolist(), messages.slave.tolist()
        for position, role in enumerate(messages.role.tolist()):
            if role == _REQUEST:
                self._requests[first + position] = int(frames.t_end_ns[position])
                if len(self._requests) > KEPT_FRAMES:
                    self._requests.popitem(last=False)
            elif answered[position] in self._requests:
                latency = max(int(frames.t_start_ns[position]) - self._requests[answered[position]], 0)
                texts[position] = f"~{latency / 1e6:.1f}"
                self.read_latency.setdefault(slaves[position], Histogram()).add(latency)
        return texts

    def recent_frames(self) -> list[tuple[AnnotatedBatch, list[str]]]:
        """The kept batches and their latency texts, as they are now."""
        return list(self._recent)

    def render(self, statistics: Statistics) -> LiveScreen:
        return LiveScreen(self, statistics)

    def status(self, statistics: Statistics) -> Text:
        state = self.state
        elapsed = time.monotonic() - state.started
        load = "" if statistics.bus_load is None else f", bus load {100 * statistics.bus_load:.1f} %"
        where = f"{state.recorded_bytes:,} bytes recorded to {state.recording}" if state.recording else "not recording"
        text = Text.assemble(
            (f"{state.port}", "bold"), f"  {state.line}  {state.timing_note}\n",
            f"{elapsed:,.0f} s, {counted(statistics.frames, 'frame')}{load}, {where}",
        )
        if state.uart_errors:
            text.append(f"\nUART errors: {state.uart_errors}", "red")
        if state.advice:
            text.append(f"\nnote: {state.advice}", "yellow")
        if state.streams:
            text.append(f"\nstreaming to {state.streams}")
        if state.behind_reads:
            text.append(f"\nthe view is behind: it skipped {state.behind_reads} reads (the recording has every byte)",
                        "yellow")
        found = diagnose(statistics, self.evidence)
        for finding in found[:SHOWN_FINDINGS]:
            text.append(f"\n{finding.severity}: {finding.sentence}", "red" if finding.severity == "error" else "yellow")
        if len(found) > SHOWN_FINDINGS:
            text.append(f"\n… and {len(found) - SHOWN_FINDINGS} more findings ('rtusniff stats' of the recording)")
        return text

    def frame_lines(self, recent: list[tuple[AnnotatedBatch, list[str]]], width: int, height: int,
                    console: Console) -> str:
        """The latest frames of ``recent`` that fit ``height`` lines (a header first), newest last."""
        layout = Layout(frame_columns(self.clock, plain=False, hex_shown=None, live=True), width,
                        terminal_colors(console))
        blocks = []
        for batch, latencies in recent:
            kept = kept_rows(batch)
            cells = frame_cells(batch.messages, kept, self.clock, plain=False, styled=layout.color_system is not None,
                                short_roles=width < NARROW, latencies=latencies)
            cells["summary"] = summary_cells(batch, kept, decoding_summary, {})
            blocks.append(cells)
        for cells in blocks:
            layout.measure(cells)
        rows = [line for cells in blocks for line in _row_texts(layout, cells)]
        shown: list[str] = []
        room = height - 1
        for row in reversed(rows):
            lines = row.count("\n")
            if lines > room:
                break
            shown.append(row)
            room -= lines
        return layout.header() + "".join(reversed(shown))


def _row_texts(layout: Layout, cells: dict[str, Cells]) -> list[str]:
    """Each row of ``cells`` laid out on its own (a row may take several lines)."""
    count = len(cells["index"].texts)
    return [layout.lines({key: Cells(c.texts[row : row + 1], c.styles[row : row + 1] if c.styles else None)
                          for key, c in cells.items()}, 1) for row in range(count)]


def slave_cells(statistics: Statistics, read_latency: dict[int, Histogram] | None = None) -> tuple[
        dict[str, Cells], int, int]:
    """Counters and latency per slave, the busiest first: the cells, the rows, the slaves. Where
    the timing measures no latency on the wire (host reads), the percentiles of ``read_latency``
    (between read times), marked ``~`` as the frames' rows mark theirs."""
    per_slave: dict[int, list[int]] = {}
    latency: dict[int, Histogram] = {}
    for (slave, _), stats in statistics.per_function.items():
        row = per_slave.setdefault(slave, [0, 0, 0, 0, 0])
        row[0] += stats.requests
        row[1] += stats.responses
        row[2] += sum(stats.exceptions.values())
        row[3] += stats.crc_errors
        row[4] += stats.timeouts
        merged = latency.setdefault(slave, Histogram())
        if stats.latency.count and stats.latency.minimum is not None and stats.latency.maximum is not None:
            merged.merge(stats.latency.counts, stats.latency.count, stats.latency.minimum, stats.latency.maximum)
    order = sorted(per_slave, key=lambda s: (-per_slave[s][0], s))
    texts: dict[str, list[str]] = {column.key: [] for column in SLAVE_COLUMNS}
    for slave in order[:SHOWN_SLAVES]:
        counts = per_slave[slave]
        for key, count in zip(("requests", "responses", "exceptions", "crc", "timeouts"), counts, strict=True):
            texts[key].append(str(count))
        texts["slave"].append(str(slave))
        between_reads = (read_latency or {}).get(slave) if not latency[slave].count else None
        for key, q in (("p50", 50), ("p95", 95)):
            if between_reads is not None:
                # Host timing: between read times, not on the wire; still the best the tap knows.
                value = between_reads.percentile(q)
                texts[key].append("" if value is None else f"~{value / 1e6:.1f}")
                continue
            value = latency[slave].percentile(q)
            texts[key].append("" if value is None else f"{value / 1e6:.1f}")
        texts["fill"].append("")
    return {key: Cells(values) for key, values in texts.items()}, min(len(order), SHOWN_SLAVES), len(order)


def slave_lines(cells: dict[str, Cells], rows: int, slaves: int, width: int, console: Console) -> str:
    layout = Layout(SLAVE_COLUMNS, width, terminal_colors(console))
    more = f"… and {slaves - rows} more slaves\n" if slaves > rows else ""
    return layout.header() + layout.lines(cells, rows) + more


class LiveScreen:
    """One redraw: what it shows is taken when it is made (in the capture's thread, which goes
    on changing the statistics and the recent frames), and laid out when rich renders it (in
    rich's refresh thread), to the terminal's size then."""

    def __init__(self, view: LiveView, statistics: Statistics) -> None:
        self.view = view
        self.status = view.status(statistics)
        self.slaves = slave_cells(statistics, view.read_latency)
        self.recent = view.recent_frames()

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        width = options.max_width
        height = options.height or console.size.height
        status = self.status
        status_lines = len(status.wrap(console, width))
        slaves = Text.from_ansi(slave_lines(*self.slaves, width, console).rstrip("\n"))
        # One line stays free: rich's live display keeps the cursor below the last line.
        room = int(height) - status_lines - len(slaves.plain.splitlines()) - 2
        frames = Text.from_ansi(self.view.frame_lines(self.recent, width, max(room, 2), console).rstrip("\n"))
        yield status
        yield slaves
        yield frames
