"""The ``stats`` command's output: tables laid out by :mod:`sniffer.views.layout` (fit to a
terminal, one line a row into a pipe), or one JSON document.

A capture with thousands of slave/function pairs prints its table in well under a second:
the rows are formatted as columns of text, never as rich table objects.
"""

from __future__ import annotations

import json
import textwrap
from typing import TYPE_CHECKING, TextIO

from decoders.capture import CaptureInfo, TimingQuality
from decoders.findings import Finding, diagnose
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.modbus.codecs import function_name
from decoders.stats import FunctionStats, Histogram, Statistics
from decoders.symptoms import Symptoms
from sniffer.sinks import Sink
from sniffer.views.layout import Cells, Column, Layout, note_lines

if TYPE_CHECKING:
    from rich.color import ColorSystem

#: What the latency cells of a host-timed capture say: read times do not measure latency.
HOST_LATENCY = "n/a"
HOST_LATENCY_NOTE = ("latency n/a: host timing (times are when the PC read the bytes; a request and its "
                     "answer often arrive in one read)")
BUS_COLUMNS = [Column("what", "bus"), Column("value", "", right=True)]
#: (key, header, keep): the per slave and function table; lower ``keep`` goes first when narrow.
FUNCTION_COLUMNS = [
    Column("slave", "slave", right=True),
    Column("function", "fc", right=True),
    Column("requests", "req", right=True),
    Column("responses", "resp", right=True),
    Column("exceptions", "exc"),
    Column("crc", "CRC", right=True),
    Column("timeouts", "timeout", right=True),
    Column("retries", "retry", right=True, keep=60),
    Column("unexpected", "unexp", right=True, keep=50),
    Column("gap_1_5", "gap1.5", right=True, keep=40),
    Column("short_idle", "short", right=True, keep=40),
    Column("min", "lat min", right=True, keep=20),
    Column("p50", "p50", right=True),
    Column("p95", "p95", right=True, keep=70),
    Column("p99", "p99", right=True, keep=10),
    Column("max", "max", right=True),
    Column("poll", "poll p50", right=True, keep=30),
    Column("name", "function name", flexible=True, min_width=8, keep=5),
]


def _ms(value_ns: float | None) -> str:
    return "" if value_ns is None else f"{value_ns / 1e6:.2f}"


def _latency_cells(histogram: Histogram, measured: bool = True) -> list[str]:
    if not measured:
        return [HOST_LATENCY] * 5
    return [_ms(histogram.minimum), _ms(histogram.percentile(50)), _ms(histogram.percentile(95)),
            _ms(histogram.percentile(99)), _ms(histogram.maximum)]


class Diagnosis(Sink):
    """The findings of a capture (:func:`decoders.findings.diagnose`): keeps nothing per message
    but their evidence, and weighs it with the statistics at the end (:attr:`findings`)."""

    wants_statistics = True
    wants_frames = True

    def __init__(self) -> None:
        self._evidence: Symptoms | None = None
        #: What is wrong on the bus, most severe first, once finished.
        self.findings: list[Finding] = []

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._evidence = Symptoms(int(line.t3_5_ns), info.timing is TimingQuality.EXACT)

    def frames(self, batch: MessageBatch) -> None:
        if self._evidence is not None:
            self._evidence.add(batch)

    def finish(self, statistics: Statistics) -> None:
        if self._evidence is not None:
            self.findings = diagnose(statistics, self._evidence)


class StatsView(Diagnosis):
    """Prints the statistics and the findings at the end."""

    def __init__(self, out: TextIO, *, width: int | None, color_system: ColorSystem | None = None,
                 as_json: bool = False) -> None:
        super().__init__()
        self._out = out
        self._width = width
        self._colors = color_system
        self._as_json = as_json
        self._header: dict[str, object] = {}
        self._latency_measured = True
        #: ``--each``: each capture's source, line and timing (provenance per capture).
        self._captures: list[dict[str, str]] = []

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        super().start(source, info, line)
        self._header = {"source": source, "line": line.format(), "timing": info.timing.value}
        self._latency_measured = info.timing is TimingQuality.EXACT

    def each_capture(self, captures: list[dict[str, str]]) -> None:
        """``--each``: the captures counted (``source``, ``line``, ``timing`` each), in order. The
        header's line and timing are theirs where all agree, else ``mixed``; the table then lists
        every setting with its captures, the JSON document every capture."""
        self._captures = captures
        for key in ("line", "timing"):
            if len({capture[key] for capture in captures}) > 1:
                self._header[key] = "mixed"
        self._latency_measured = any(capture["timing"] == TimingQuality.EXACT.value for capture in captures)

    def finish(self, statistics: Statistics) -> None:
        # Over several captures (--each) the frames were counted elsewhere: no evidence to weigh.
        if not self._captures:
            super().finish(statistics)
        findings = [] if self._captures else self.findings
        if self._as_json:
            measured = {"latency_measured": self._latency_measured}
            each = {"captures": self._captures} if self._captures else {}
            drawn = {} if self._captures else {"findings": [finding.to_dict() for finding in findings]}
            self._out.write(json.dumps({**self._header, **measured, **each, **statistics.to_dict(), **drawn},
                                       indent=2) + "\n")
            return
        header = self._header
        self._note(f"{header['source']}  line {header['line']}  timing {header['timing']}")
        if "mixed" in (header["line"], header["timing"]):
            for setting, sources in _by_setting(self._captures).items():
                shown = ", ".join(sources[:SOURCES_SHOWN]) + (", …" if len(sources) > SOURCES_SHOWN else "")
                self._note(f"  {setting}: {len(sources)} capture{'s' if len(sources) != 1 else ''} ({shown})")
        self._out.write(self._bus_lines(statistics))
        self._out.write("\n")
        self._note("per slave and function (latency and poll period in ms)")
        self._out.write(self._function_lines(statistics))
        if not self._latency_measured:
            self._note(HOST_LATENCY_NOTE)
        if findings:
            self._out.write("\n")
            self._note(f"findings ({len(findings)}; 'rtusniff report' shows their frames)")
            self._out.write(finding_lines(findings, self._width))
        self._out.flush()

    def _note(self, text: str) -> None:
        if self._width is None:
            self._out.write(f"# {text}\n")
        else:
            self._out.write("".join(f"{line}\n" for line in note_lines(text, self._width)))

    def _bus_lines(self, s: Statistics) -> str:
        unit = "" if self._width is None else " "  # one field per cell in a pipe
        load = "" if s.bus_load is None else f"{100 * s.bus_load:.1f}{unit}%"
        rows = [
            ("frames", str(s.frames)), ("bytes", str(s.total_bytes)),
            ("duration", f"{s.duration_ns / 1e9:.3f}{unit}s"),
            ("bus_load" if self._width is None else "bus load", load), ("crc_errors" if self._width is None
                                                                         else "CRC errors", str(s.crc_errors)),
            ("noise_bytes" if self._width is None else "noise bytes", str(s.noise_bytes)),
        ]
        joint = "_" if self._width is None else " "
        # Only a capture that carries them (a logic analyzer's) can show UART errors.
        rows += [(f"uart{joint}{kind}{joint}errors", str(count)) for kind, count in
                 (("framing", s.uart_framing_errors), ("parity", s.uart_parity_errors)) if count]
        rows += [(f"role{joint}{role}", str(n)) for role, n in sorted(s.roles.items())]
        rows += [(f"flag{joint}{flag}", str(n)) for flag, n in sorted(s.flags.items())]
        layout = Layout(BUS_COLUMNS, self._width, self._colors)
        cells = {"what": Cells([r[0] for r in rows]), "value": Cells([r[1] for r in rows])}
        return layout.lines(cells, len(rows))

    def _function_lines(self, s: Statistics) -> str:
        keys = [c.key for c in FUNCTION_COLUMNS]
        texts: dict[str, list[str]] = {key: [] for key in keys}
        styles: dict[str, list[str]] = {key: [] for key in keys}
        for (slave, function), stats in sorted(s.per_function.items()):
            row = self._cells(slave, function, stats)
            for key in keys:
                text = row.get(key, "")
                texts[key].append(text)
                styles[key].append(_STYLES.get(key, "") if text not in ("", "0") else "")
        layout = Layout(FUNCTION_COLUMNS, self._width, self._colors)
        cells = {key: Cells(texts[key], styles[key] if self._colors else None) for key in keys}
        count = len(s.per_function)
        layout.measure(cells)
        lines = layout.header() + layout.lines(cells, count)
        if layout.hidden():
            note = f"(no room at {self._width} columns for: {', '.join(layout.hidden())}; --format json has all)"
            lines += "".join(f"{line}\n" for line in textwrap.wrap(note, self._width or len(note)))
        return lines

    def _cells(self, slave: int, function: int, f: FunctionStats) -> dict[str, str]:
        exceptions = (" " if self._width else ",").join(f"{code:02X}×{n}" for code, n in sorted(f.exceptions.items()))
        latency = _latency_cells(f.latency, self._latency_measured)
        return {
            "slave": str(slave), "function": str(function), "requests": str(f.requests + f.broadcasts),
            "responses": str(f.responses), "exceptions": exceptions, "crc": str(f.crc_errors),
            "timeouts": str(f.timeouts), "retries": str(f.retries), "unexpected": str(f.unexpected),
            "gap_1_5": str(f.gap_1_5), "short_idle": str(f.short_idle), "min": latency[0], "p50": latency[1],
            "p95": latency[2], "p99": latency[3], "max": latency[4], "poll": _ms(f.poll_period.percentile(50)),
            "name": function_name(function),
        }


def finding_lines(findings: list[Finding], width: int | None) -> str:
    """Each finding as its severity and sentence, then the frames that show it and what to check:
    wrapped at words to ``width``, or a line each into a pipe (``None``)."""
    lines = []
    for finding in findings:
        frames = f" (frames {', '.join(f'#{index}' for index in finding.frames)})" if finding.frames else ""
        parts = [f"{finding.severity:7}  {finding.sentence}{frames}"]
        if finding.causes:
            parts.append(f"         check: {'; '.join(finding.causes)}")
        for part in parts:
            if width is None:
                lines.append(part)
            else:
                lines += textwrap.wrap(part, width, subsequent_indent=" " * 9, break_long_words=False,
                                       break_on_hyphens=False)
    return "".join(f"{line}\n" for line in lines)


_STYLES = {"exceptions": "red", "crc": "red", "timeouts": "red", "retries": "yellow", "unexpected": "yellow",
           "gap_1_5": "yellow", "short_idle": "yellow"}


#: Captures named per line setting in the table of ``stats --each`` (the JSON lists all).
SOURCES_SHOWN = 3


def _by_setting(captures: list[dict[str, str]]) -> dict[str, list[str]]:
    """The captures' sources by their line and timing (``9600 8N1, timing exact``), in order met."""
    settings: dict[str, list[str]] = {}
    for capture in captures:
        settings.setdefault(f"line {capture['line']}, timing {capture['timing']}", []).append(capture["source"])
    return settings
