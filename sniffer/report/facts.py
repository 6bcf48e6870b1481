"""What both report formats say, as texts: provenance, the bus summary, the health table.

The HTML (:mod:`sniffer.report.html`) and the Markdown (:mod:`sniffer.report.markdown`) reports
lay these out; neither computes a figure of its own, so the two always agree.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass

from decoders.capture import guessed_line
from decoders.health import SlaveHealth, slave_health
from decoders.message import DeviceIdentity
from decoders.stats import Histogram, Statistics
from sniffer.report.anomalies import utc_text
from sniffer.report.collect import Comparison, ReportCollector
from sniffer.views.compare_view import COLUMNS as COMPARISON_COLUMNS
from sniffer.views.compare_view import comparison_cells, verdict_counts

#: The health table's columns: key, heading, right-aligned.
HEALTH_COLUMNS = (
    ("slave", "slave", True), ("device", "device", False), ("functions", "functions", False),
    ("requests", "requests", True), ("responses", "answers", True), ("exceptions", "exceptions", False),
    ("crc_errors", "CRC errors", True), ("timeouts", "timeouts", True), ("retries", "retries", True),
    ("error_rate", "error rate", True), ("p50", "lat p50 ms", True), ("p95", "p95 ms", True),
    ("max", "max ms", True), ("poll", "poll ms", True),
)
#: An error rate at or above this is shown as bad, above 0 as a warning.
BAD_RATE = 0.01


@dataclass(frozen=True)
class HealthRow:
    cells: dict[str, str]
    #: ``bad``, ``warn`` or ``good``: how the error rate looks.
    grade: str


#: More capture files than this are listed one line each, and the title names the first and last.
MANY_FILES = 4


def report_title(collector: ReportCollector) -> str:
    files = collector.provenance.files
    if len(files) > MANY_FILES:
        return f"Modbus RTU report: {len(files):,} captures, {files[0].path} … {files[-1].path}"
    return "Modbus RTU report: " + " + ".join(file.path for file in files)


def provenance_facts(collector: ReportCollector) -> list[tuple[str, str]]:
    """Label and text of every provenance fact, in the order a reader checks them."""
    p, s = collector.provenance, collector.statistics
    facts = []
    if p.merged:
        facts.append(("captures", f"{len(p.files):,} files, each read on its own and merged (--each); rows name "
                      "their file"))
    for file in p.files:
        if len(p.files) > MANY_FILES:
            facts.append(("file", f"{file.path}: {file.size:,} bytes, SHA-256 {file.sha256}" if file.sha256
                          else file.path))
            continue
        facts.append(("file", file.path))
        if file.sha256:
            facts += [("size", f"{file.size:,} bytes"), ("SHA-256", file.sha256)]
    if s.first_ns is not None and s.last_ns is not None:
        facts += [("first frame", f"{utc_text(s.first_ns)} UTC"), ("last frame", f"{utc_text(s.last_ns)} UTC"),
                  ("duration", duration_text(s.duration_ns))]
    if p.window:
        facts.append(("part read", p.window))
    guessed = guessed_line(p.notes)
    facts += [("line", f"{p.line} (guessed, not given: {guessed})" if guessed else p.line),
              ("timing", timing_text(p.timing))]
    if p.channels:
        facts.append(("channels", ", ".join(p.channels)))
    facts.append(("profiles", profiles_text(collector)))
    unnamed = _identified_in_some(collector)
    if unnamed:
        facts.append(("identification", unnamed))
    facts += [("tool", f"rtusniff {p.tool_version}"), ("command", p.command)]
    facts += [("capture note", note) for note in p.notes]
    return facts


def timing_text(timing: str) -> str:
    if ", " in timing:
        return (f"{timing}: the captures differ (exact: times of bytes on the wire; host: times the PC read "
                "them)")
    if timing == "exact":
        return "exact: times are when each byte was on the wire; silences and latencies are measured"
    return (f"{timing}: times are when the PC read the bytes; frames are found from their content, latencies "
            "are between reads")


def profiles_text(collector: ReportCollector) -> str:
    chosen = collector.provenance.profiles
    devices = sorted(collector.provenance.devices.items())
    identified = [f"slave {slave}: {device.profile} ({device.product_code}, identified)"
                  for slave, device in devices if device.applied and device.profile]
    parts = [f"--profile {name}" for name in chosen] + identified
    return "; ".join(parts) if parts else "none (registers shown as numbers)"


def duration_text(ns: int) -> str:
    seconds = ns / 1e9
    if seconds < 60:
        return f"{seconds:.3f} s"
    minutes, rest = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min {rest:02d} s" if hours else f"{minutes} min {rest:02d} s"


def bus_summary(collector: ReportCollector) -> list[tuple[str, str, str]]:
    """Label, value and grade (``bad``/``warn``/``""``) of the bus's headline figures."""
    s, counts = collector.statistics, collector.anomalies.counts
    frames = s.frames or 1
    summary = [
        ("frames", f"{s.frames:,}", ""),
        ("bytes", f"{s.total_bytes:,}", ""),
        ("bus load", _load(s), ""),
        ("CRC errors", f"{s.crc_errors:,} ({s.crc_errors / frames * 100:.2f} %)", _grade(s.crc_errors / frames)),
        ("timeouts", f"{counts['timeout']:,}", _grade(counts["timeout"] / frames)),
        ("exceptions", f"{counts['exception']:,}", _grade(counts["exception"] / frames)),
        ("noise bytes", f"{s.noise_bytes:,}", _grade(s.noise_bytes / max(s.total_bytes, 1))),
    ]
    if s.uart_framing_errors or s.uart_parity_errors:
        summary.append(("UART errors", f"{s.uart_framing_errors:,} framing, {s.uart_parity_errors:,} parity", "bad"))
    return summary


def _grade(rate: float) -> str:
    return "bad" if rate >= BAD_RATE else "warn" if rate > 0 else ""


def health_rows(collector: ReportCollector) -> list[HealthRow]:
    devices = collector.provenance.devices
    return [_health_row(row, devices.get(row.slave)) for row in slave_health(collector.statistics)]


def _health_row(row: SlaveHealth, device: DeviceIdentity | None) -> HealthRow:
    rate = row.error_rate
    name = device.product_code if device is not None else ""
    cells = {
        "slave": "0 (broadcast)" if row.slave == 0 else str(row.slave),
        "device": name,
        "functions": ", ".join(map(str, row.functions)),
        "requests": f"{row.requests:,}",
        "responses": f"{row.responses:,}",
        "exceptions": ", ".join(f"{code:02d}×{n}" for code, n in sorted(row.exceptions.items())) or "0",
        "crc_errors": f"{row.crc_errors:,}",
        "timeouts": f"{row.timeouts:,}",
        "retries": f"{row.retries:,}",
        "error_rate": "–" if rate is None else f"{rate * 100:.2f} %",
        "p50": _ms(row.latency, 50), "p95": _ms(row.latency, 95), "max": _ms_max(row.latency),
        "poll": _ms(row.poll_period, 50),
    }
    return HealthRow(cells, "" if rate is None else _grade(rate) or "good")


def _ms(histogram: Histogram, q: float) -> str:
    value = histogram.percentile(q)
    return "–" if value is None else f"{value / 1e6:.2f}"


def _ms_max(histogram: Histogram) -> str:
    return "–" if histogram.maximum is None else f"{histogram.maximum / 1e6:.2f}"


def comparison_facts(comparison: Comparison) -> tuple[list[str], list[tuple[str, str, str]]]:
    """What the section "before and after" says first: the two captures, and the totals."""
    b, a = comparison.before, comparison.after
    lines = [f"before: {b.source} (SHA-256 {comparison.baseline.sha256 or 'n/a'}), line {b.line}, timing {b.timing}",
             f"after: {a.source}, line {a.line}, timing {a.timing}"]
    totals = [("frames", f"{b.statistics.frames:,}", f"{a.statistics.frames:,}"),
              ("CRC errors", f"{b.statistics.crc_errors:,}", f"{a.statistics.crc_errors:,}"),
              ("bus load", _load(b.statistics), _load(a.statistics))]
    return lines, totals


def comparison_rows(comparison: Comparison) -> tuple[list[tuple[str, str, bool]], list[dict[str, str]], str]:
    """The comparison's columns (key, heading, right-aligned), its rows, and the verdicts' count."""
    columns = [(column.key, column.header, column.right) for column in COMPARISON_COLUMNS]
    rows = [comparison_cells(change, comparison.before, comparison.after) for change in comparison.changes]
    return columns, rows, verdict_counts(comparison.changes)


def _load(statistics: Statistics) -> str:
    return "–" if statistics.bus_load is None else f"{statistics.bus_load * 100:.1f} %"


def _identified_in_some(collector: ReportCollector) -> str:
    """``--each``: the slaves that identified themselves in some captures only. Each capture is
    read knowing nothing, so in the others their values went unnamed; the remedy is the option."""
    p = collector.provenance
    if not p.merged or any("=" not in choice for choice in p.profiles):
        return ""
    chosen = {int(choice.split("=")[0]) for choice in p.profiles}
    some = {slave: count for slave, count in sorted(p.identified_in.items())
            if count < len(p.files) and slave not in chosen and p.devices[slave].profile is not None}
    if not some:
        return ""
    slaves = ", ".join(f"{slave} (in {count} of {len(p.files)} captures)" for slave, count in some.items())
    options = " ".join(f"--profile {slave}={p.devices[slave].profile}" for slave in some)
    return (f"slaves {slaves} identified themselves (FC 43) in some captures only; each capture is read on its "
            f"own, so elsewhere their values are not named. To name them in every capture: {options}")


def capture_argument(collector: ReportCollector) -> str:
    """The capture files as a shell command takes them (the report's "show it in full" hint);
    ``FILE`` where the files were read one by one (each row names its own)."""
    if collector.provenance.merged:
        return "FILE"
    return " ".join(shlex.quote(file.path) for file in collector.provenance.files)
