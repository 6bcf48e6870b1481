"""The ``compare`` command's output: two captures side by side, per slave and function
(:mod:`decoders.compare`), as a table laid out by :mod:`sniffer.views.layout` or one JSON document.

Each cell says ``before→after`` (no spaces: into a pipe every cell stays one awk field).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TextIO

from decoders.compare import Change, Measures
from decoders.modbus.codecs import function_name
from decoders.stats import Statistics
from sniffer.views.layout import Cells, Column, Layout, note_lines

if TYPE_CHECKING:
    from rich.color import ColorSystem

COLUMNS = [
    Column("slave", "slave", right=True),
    Column("function", "fc", right=True),
    Column("requests", "requests", right=True, keep=40),
    Column("errors", "errors %", right=True),
    Column("timeouts", "timeouts %", right=True, keep=50),
    Column("p50", "lat p50", right=True, keep=30),
    Column("p95", "lat p95", right=True),
    Column("max", "lat max", right=True, keep=20),
    Column("poll", "poll p50", right=True, keep=10),
    Column("verdict", "verdict"),
    Column("name", "function name", flexible=True, min_width=8, keep=5),
]
_STYLES = {"worse": "bold red", "better": "green", "gone": "yellow", "new": "yellow"}


@dataclass(frozen=True)
class Side:
    """One capture: where it came from and what it counted."""

    source: str
    line: str
    timing: str
    statistics: Statistics

    @property
    def latency_measured(self) -> bool:
        return self.timing == "exact"


def write_comparison(out: TextIO, before: Side, after: Side, changes: list[Change], *, as_json: bool,
                     width: int | None, colors: ColorSystem | None) -> None:
    if as_json:
        out.write(json.dumps(_document(before, after, changes), indent=2) + "\n")
        return
    _note(out, width, f"before: {before.source}  line {before.line}  timing {before.timing}")
    _note(out, width, f"after:  {after.source}  line {after.line}  timing {after.timing}")
    _note(out, width, f"frames {before.statistics.frames}→{after.statistics.frames}, CRC errors "
                      f"{before.statistics.crc_errors}→{after.statistics.crc_errors}, bus load "
                      f"{_load(before.statistics)}→{_load(after.statistics)}")
    _note(out, width, "per slave and function, before→after (latency and poll period in ms)")
    rows = [comparison_cells(change, before, after) for change in changes]
    keys = [column.key for column in COLUMNS]
    styles = [_STYLES.get(change.verdict, "") for change in changes]
    cells = {key: Cells([row[key] for row in rows], styles if key == "verdict" and colors else None) for key in keys}
    layout = Layout(COLUMNS, width, colors)
    layout.measure(cells)
    out.write(layout.header() + layout.lines(cells, len(rows)))
    if layout.hidden():
        _note(out, width, f"(no room at {width} columns for: {', '.join(layout.hidden())}; --format json has all)")
    _note(out, width, verdict_counts(changes))
    if not (before.latency_measured and after.latency_measured):
        _note(out, width, "latency n/a on a host-timed capture (read times do not measure it)")
    out.flush()


def _note(out: TextIO, width: int | None, text: str) -> None:
    if width is None:
        out.write(f"# {text}\n")
    else:
        out.write("".join(f"{line}\n" for line in note_lines(text, width)))


def _load(statistics: Statistics) -> str:
    return "-" if statistics.bus_load is None else f"{100 * statistics.bus_load:.1f}%"


def verdict_counts(changes: list[Change]) -> str:
    """``2 worse, 5 same``: how many pairs got each verdict."""
    counts = {verdict: sum(change.verdict == verdict for change in changes)
              for verdict in ("worse", "better", "same", "new", "gone")}
    return ", ".join(f"{n} {verdict}" for verdict, n in counts.items() if n) or "nothing to compare"


def comparison_cells(change: Change, before: Side, after: Side) -> dict[str, str]:
    """The texts of one row, by the keys of :data:`COLUMNS`."""
    b, a = change.before, change.after
    timed = (before.latency_measured, after.latency_measured)
    return {
        "slave": str(change.slave),
        "function": str(change.function),
        "requests": _pair(b, a, lambda m, _: str(m.requests)),
        "errors": _pair(b, a, lambda m, _: _percent(m.error_rate)),
        "timeouts": _pair(b, a, lambda m, _: _percent(m.timeout_rate)),
        "p50": _pair(b, a, lambda m, side: _ms(m.latency_p50_ns, timed[side])),
        "p95": _pair(b, a, lambda m, side: _ms(m.latency_p95_ns, timed[side])),
        "max": _pair(b, a, lambda m, side: _ms(m.latency_max_ns, timed[side])),
        "poll": _pair(b, a, lambda m, _: _ms(m.poll_p50_ns, True)),
        "verdict": change.verdict,
        "name": function_name(change.function),
    }


def _pair(before: Measures | None, after: Measures | None, text: Any) -> str:
    return "→".join("-" if m is None else text(m, side) for side, m in enumerate((before, after)))


def _percent(rate: float | None) -> str:
    return "-" if rate is None else f"{100 * rate:.1f}"


def _ms(value_ns: float | None, measured: bool) -> str:
    if not measured:
        return "n/a"
    return "-" if value_ns is None else f"{value_ns / 1e6:.2f}"


def _document(before: Side, after: Side, changes: list[Change]) -> dict[str, Any]:
    def side(s: Side) -> dict[str, Any]:
        stats = s.statistics.to_dict()
        return {"source": s.source, "line": s.line, "timing": s.timing, "latency_measured": s.latency_measured,
                **{key: stats[key] for key in ("frames", "duration_s", "bus_load", "crc_errors", "noise_bytes")}}

    def measures(m: Measures | None, measured: bool) -> dict[str, Any] | None:
        if m is None:
            return None

        def seconds(ns: float | None) -> float | None:
            return None if ns is None or not measured else ns / 1e9

        return {"requests": m.requests, "responses": m.responses, "exceptions": m.exceptions,
                "crc_errors": m.crc_errors, "timeouts": m.timeouts, "retries": m.retries,
                "error_rate": m.error_rate, "timeout_rate": m.timeout_rate,
                "latency_p50_s": seconds(m.latency_p50_ns), "latency_p95_s": seconds(m.latency_p95_ns),
                "latency_max_s": seconds(m.latency_max_ns),
                "poll_period_p50_s": None if m.poll_p50_ns is None else m.poll_p50_ns / 1e9}

    return {
        "before": side(before),
        "after": side(after),
        "per_slave_function": [
            {"slave": c.slave, "function": c.function, "verdict": c.verdict,
             "before": measures(c.before, before.latency_measured), "after": measures(c.after, after.latency_measured)}
            for c in changes
        ],
    }
