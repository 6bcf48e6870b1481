"""The terminal table view of ``analyze``.

Rows are printed in blocks as they are decoded, each block a rich table with the
same fixed column widths, so that memory does not grow with the capture and the
output reads as one table.
"""

from __future__ import annotations

from datetime import UTC, datetime

from rich.console import Console
from rich.table import Table
from rich.text import Text

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, Message, Role
from decoders.stats import Statistics
from sniffer.sinks import Sink

ROWS_PER_BLOCK = 200
#: (header, width, justify); the hex column takes the rest of the width.
COLUMNS: list[tuple[str, int, str]] = [
    ("#", 6, "right"),
    ("time (UTC)", 15, "left"),
    ("Δt ms", 9, "right"),
    ("slave", 5, "right"),
    ("fc", 3, "right"),
    ("role", 9, "left"),
    ("req", 6, "right"),
    ("len", 4, "right"),
    ("CRC", 4, "left"),
    ("flags", 12, "left"),
]
ROLE_STYLES = {
    Role.REQUEST: "cyan",
    Role.RESPONSE: "green",
    Role.EXCEPTION: "bold red",
    Role.BROADCAST: "magenta",
    Role.NOISE: "dim",
    Role.UNKNOWN: "yellow",
}


def format_clock(t_ns: int) -> str:
    """``HH:MM:SS.ffffff`` in UTC."""
    seconds, nanos = divmod(t_ns, 1_000_000_000)
    clock = datetime.fromtimestamp(seconds, UTC).strftime("%H:%M:%S")
    return f"{clock}.{nanos // 1000:06d}"


class TableView(Sink):
    """Prints a heading, the frames in blocks, and a closing count."""

    def __init__(self, console: Console) -> None:
        self._console = console
        self._header_shown = False

    wants_messages = True
    wants_statistics = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._console.print(
            f"[bold]{source}[/]  line {line.format()}  timing [bold]{info.timing.value}[/]"
            f"  t1.5 {line.t1_5_ns / 1e3:.0f} µs  t3.5 {line.t3_5_ns / 1e3:.0f} µs",
            highlight=False,
        )
        if info.timing is TimingQuality.HOST:
            self._console.print(
                "[yellow]host timing[/]: times are when the PC read the bytes (USB adapters deliver "
                "them in bursts, up to their latency timer late); frames are found from their content, "
                "and silences inside or between them are not measured (no gap_1_5 / short_idle).",
                highlight=False,
            )
        self._date_shown = False

    def messages(self, batch: AnnotatedBatch) -> None:
        messages = list(batch)
        for start in range(0, len(messages), ROWS_PER_BLOCK):
            self._print_block(messages[start : start + ROWS_PER_BLOCK])

    def _print_block(self, messages: list[Message]) -> None:
        if not messages:
            return
        if not self._date_shown:
            first = datetime.fromtimestamp(messages[0].frame.t_start_ns // 1_000_000_000, UTC)
            self._console.print(f"capture starts {first:%Y-%m-%d %H:%M:%S} UTC", highlight=False)
            self._date_shown = True
        table = Table(show_header=not self._header_shown, box=None, pad_edge=False, expand=True)
        for header, width, justify in COLUMNS:
            table.add_column(header, width=width, no_wrap=header != "flags", justify=justify)  # type: ignore[arg-type]
        table.add_column("summary", ratio=3, overflow="fold")
        table.add_column("hex", ratio=2, overflow="fold")
        for message in messages:
            table.add_row(*self._cells(message))
        self._header_shown = True
        self._console.print(table)

    def _cells(self, message: Message) -> list[Text | str]:
        frame = message.frame
        idle = "" if frame.idle_before_ns is None else f"{frame.idle_before_ns / 1e6:.3f}"
        crc = Text("ok", "green") if frame.crc_ok else Text("BAD", "bold red")
        if message.role is Role.NOISE:
            crc = Text("")
        return [
            str(frame.index),
            format_clock(frame.t_start_ns),
            idle,
            "" if message.slave is None else str(message.slave),
            "" if message.function is None else str(message.function),
            Text(message.role.value, ROLE_STYLES[message.role]),
            "" if message.request_index is None else f"#{message.request_index}",
            str(len(frame.data)),
            crc,
            Text(" ".join(message.flags.names), "yellow"),
            _summary_cell(message),
            frame.data.hex(" "),
        ]

    def finish(self, statistics: Statistics) -> None:
        roles, flags = statistics.roles, statistics.flags
        order = ["request", "response", "exception", "broadcast", "unknown", "noise"]
        parts = [f"{statistics.frames} frames"] + [f"{roles[r]} {r}" for r in order if roles[r]]
        if statistics.crc_errors:
            parts.append(f"{statistics.crc_errors} CRC errors")
        parts += [f"{n} {flag}" for flag, n in sorted(flags.items())]
        self._console.print(", ".join(parts), highlight=False)


def _summary_cell(message: Message) -> Text:
    text = Text(message.summary)
    for remark in message.remarks:
        text.append(f" ⚠ {remark}", "yellow")
    return text
