"""The ``stats`` command's output: rich tables, or one JSON document."""

from __future__ import annotations

import json
from typing import TextIO

from rich.console import Console
from rich.table import Table

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch
from decoders.modbus.codes import function_name
from decoders.stats import FunctionStats, Histogram, Statistics
from sniffer.sinks import Sink


def _ms(value_ns: float | None) -> str:
    return "" if value_ns is None else f"{value_ns / 1e6:.2f}"


#: What the latency cells of a host-timed capture say: read times do not measure latency.
HOST_LATENCY = "n/a"
HOST_LATENCY_NOTE = ("latency n/a: host timing (times are when the PC read the bytes; a request and its "
                     "answer often arrive in one read)")


def _latency_cells(histogram: Histogram, measured: bool = True) -> list[str]:
    if not measured:
        return [HOST_LATENCY] * 5
    return [
        _ms(histogram.minimum),
        _ms(histogram.percentile(50)),
        _ms(histogram.percentile(95)),
        _ms(histogram.percentile(99)),
        _ms(histogram.maximum),
    ]


def _count(value: int, style: str = "red") -> str:
    return f"[{style}]{value}[/]" if value else "0"


class StatsView(Sink):
    """Keeps nothing per message; prints the statistics at the end."""

    def __init__(self, out: TextIO, console: Console, as_json: bool) -> None:
        self._out = out
        self._console = console
        self._as_json = as_json
        self._header: dict[str, object] = {}
        self._latency_measured = True

    wants_messages = False
    wants_statistics = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._header = {"source": source, "line": line.format(), "timing": info.timing.value}
        self._latency_measured = info.timing is TimingQuality.EXACT

    def messages(self, batch: AnnotatedBatch) -> None:
        pass

    def finish(self, statistics: Statistics) -> None:
        if self._as_json:
            measured = {"latency_measured": self._latency_measured}
            self._out.write(json.dumps({**self._header, **measured, **statistics.to_dict()}, indent=2) + "\n")
            return
        header = self._header
        self._console.print(f"[bold]{header['source']}[/]  line {header['line']}  timing {header['timing']}")
        self._console.print(self._bus_table(statistics))
        self._console.print(self._function_table(statistics))
        if not self._latency_measured:
            self._console.print(HOST_LATENCY_NOTE, style="yellow")

    def _bus_table(self, s: Statistics) -> Table:
        table = Table(show_header=False)
        table.add_column("what")
        table.add_column("value", justify="right")
        load = "" if s.bus_load is None else f"{100 * s.bus_load:.1f} %"
        rows = [
            ("frames", str(s.frames)), ("bytes", str(s.total_bytes)), ("duration", f"{s.duration_ns / 1e9:.3f} s"),
            ("bus load", load), ("CRC errors", _count(s.crc_errors)), ("noise bytes", _count(s.noise_bytes)),
        ]
        rows += [(f"role {role}", str(n)) for role, n in sorted(s.roles.items())]
        rows += [(f"flag {flag}", _count(n, "yellow")) for flag, n in sorted(s.flags.items())]
        for row in rows:
            table.add_row(*row)
        return table

    def _function_table(self, s: Statistics) -> Table:
        table = Table(title="per slave and function (latency and poll period in ms)", title_justify="left")
        headers = ["slave", "function", "req", "resp", "exc", "CRC", "timeout", "retry", "unexp", "gap1.5",
                   "short", "lat min", "p50", "p95", "p99", "max", "poll p50"]
        for header in headers:
            table.add_column(header, justify="left" if header == "function" else "right")
        for (slave, function), stats in sorted(s.per_function.items()):
            name = f"{function} {function_name(function)}"
            table.add_row(str(slave), name, *self._cells(stats, self._latency_measured))
        return table

    @staticmethod
    def _cells(f: FunctionStats, latency_measured: bool) -> list[str]:
        exceptions = " ".join(f"{code:02X}×{n}" for code, n in sorted(f.exceptions.items()))
        return [
            str(f.requests + f.broadcasts), str(f.responses), f"[red]{exceptions}[/]" if exceptions else "",
            _count(f.crc_errors), _count(f.timeouts), _count(f.retries, "yellow"), _count(f.unexpected, "yellow"),
            _count(f.gap_1_5, "yellow"), _count(f.short_idle, "yellow"),
            *_latency_cells(f.latency, latency_measured), _ms(f.poll_period.percentile(50)),
        ]
