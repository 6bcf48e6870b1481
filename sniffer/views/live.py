"""The live terminal view of ``capture``: redrawn a few times a second."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

from rich.console import Group, RenderableType
from rich.table import Table
from rich.text import Text

from decoders.message import AnnotatedBatch, Message
from decoders.stats import Histogram, Statistics
from sniffer.sinks import Sink
from sniffer.views.table import ROLE_STYLES, format_clock

RECENT_FRAMES = 15


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
    started: float = field(default_factory=time.monotonic)


class LiveView(Sink):
    """Keeps the last frames and renders the status, per-slave counters and recent frames."""

    def __init__(self, state: LiveState) -> None:
        self.state = state
        self._recent: deque[Message] = deque(maxlen=RECENT_FRAMES)

    wants_messages = True
    wants_statistics = True

    def messages(self, batch: AnnotatedBatch) -> None:
        self.add(list(batch))

    def add(self, messages: list[Message]) -> None:
        self._recent.extend(messages)

    def render(self, statistics: Statistics) -> RenderableType:
        return Group(self._status(statistics), self._slaves(statistics), self._frames())

    def _status(self, statistics: Statistics) -> Text:
        state = self.state
        elapsed = time.monotonic() - state.started
        load = "" if statistics.bus_load is None else f", bus load {100 * statistics.bus_load:.1f} %"
        where = f"{state.recorded_bytes:,} bytes recorded to {state.recording}" if state.recording else "not recording"
        text = Text.assemble(
            (f"{state.port}", "bold"), f"  {state.line}  {state.timing_note}\n",
            f"{elapsed:,.0f} s, {statistics.frames:,} frames{load}, {where}\n",
        )
        if state.uart_errors:
            text.append(f"UART errors: {state.uart_errors}\n", "red")
        if state.advice:
            text.append(f"note: {state.advice}\n", "yellow")
        if state.behind_reads:
            text.append(f"the view is behind: it skipped {state.behind_reads} reads (the recording has every byte)\n",
                        "yellow")
        return text

    @staticmethod
    def _slaves(statistics: Statistics) -> Table:
        table = Table(title="per slave", title_justify="left", expand=False)
        for header in ("slave", "requests", "responses", "exceptions", "CRC errors", "timeouts", "lat p50 ms",
                       "lat p95 ms"):
            table.add_column(header, justify="right")
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
        for slave in sorted(per_slave):
            p50, p95 = latency[slave].percentile(50), latency[slave].percentile(95)
            # A live tap reads the port: host timing, latencies not measured (say so, never 0.00).
            table.add_row(str(slave), *map(str, per_slave[slave]),
                          "n/a" if p50 is None else f"{p50 / 1e6:.2f}", "n/a" if p95 is None else f"{p95 / 1e6:.2f}")
        return table

    def _frames(self) -> Table:
        table = Table(title="recent frames", title_justify="left", expand=True)
        for header, width in (("time (UTC)", 15), ("slave", 5), ("fc", 3), ("role", 9), ("flags", 14)):
            table.add_column(header, width=width, no_wrap=True)
        table.add_column("summary", ratio=1, overflow="fold")
        for message in self._recent:
            table.add_row(
                format_clock(message.frame.t_start_ns),
                "" if message.slave is None else str(message.slave),
                "" if message.function is None else str(message.function),
                Text(message.role.value, ROLE_STYLES[message.role]),
                Text(" ".join(message.flags.names), "yellow"),
                message.summary,
            )
        return table
