"""The HTML report: one self-contained file (styles, script and data inline; no request to any
network), readable offline from a mail attachment. Charts are drawn by ``assets/report.js``
from the data of :mod:`sniffer.report.charts`; everything else is plain HTML written here."""

from __future__ import annotations

import json
from collections.abc import Sequence
from html import escape
from importlib.resources import files
from typing import TextIO

from decoders.anomalies import KINDS
from sniffer.report.anomalies import Anomaly, FrameRow, utc_text
from sniffer.report.charts import chart_data
from sniffer.report.collect import Comparison, ReportCollector
from sniffer.report.drive_values import MAX_CHANGES
from sniffer.report.facts import (
    HEALTH_COLUMNS,
    bus_summary,
    capture_argument,
    comparison_facts,
    comparison_rows,
    health_rows,
    provenance_facts,
    report_title,
)

#: A kind of anomaly with no more than this many is shown unfolded.
OPEN_UP_TO = 20
_ROW_COLUMNS = (("index", "#", True), ("time", "time (UTC)", False), ("idle_ms", "Δt ms", True),
                ("slave", "slave", True), ("function", "fc", True), ("role", "role", False),
                ("latency_ms", "lat ms", True), ("crc", "CRC", False), ("flags", "flags", False),
                ("hex", "hex", False), ("summary", "decoded", False))


def _asset(name: str) -> str:
    return files("sniffer.report").joinpath("assets", name).read_text(encoding="utf-8")


def write_html(out: TextIO, collector: ReportCollector, comparison: Comparison | None = None) -> None:
    title = report_title(collector)
    data = json.dumps(chart_data(collector), separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    parts = [
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n",
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n",
        # No network, ever: the page may only use what it carries.
        "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'; "
        "script-src 'unsafe-inline'; img-src data:\">\n",
        f"<title>{escape(title)}</title>\n<style>\n{_asset('report.css')}</style>\n</head>\n<body>\n",
        f"<h1>{escape(title)}</h1>\n",
        "<p class=\"lead\">Made by rtusniff from the capture named below; every figure can be checked with the "
        "command it gives. Times are UTC.</p>\n",
        _findings(collector), _summary(collector), _health(collector),
        _comparison(comparison) if comparison else "", _anomalies(collector), _charts(collector),
        _state_changes(collector), _provenance(collector),
        f"<script type=\"application/json\" id=\"report-data\">{data}</script>\n",
        f"<script>\n{_asset('report.js')}</script>\n</body>\n</html>\n",
    ]
    out.write("".join(parts))


def _findings(collector: ReportCollector) -> str:
    """What is wrong, first: each finding's sentence, the frames that show it, what to check, and
    a link to the anomalies that hold its frames."""
    items = []
    for capture, finding in collector.findings:
        where = f"<span class=\"capture\">{escape(capture)}</span> " if capture else ""
        frames = f" <span class=\"frames\">frames {', '.join(f'#{i}' for i in finding.frames)}</span>" \
            if finding.frames else ""
        links = "".join(f" → <a href=\"#anomaly-{kind}\">{escape(KINDS[kind][0])}</a>" for kind in finding.kinds
                        if collector.anomalies.counts[kind])
        check = f"<div class=\"check\">Check: {escape('; '.join(finding.causes))}.</div>" if finding.causes else ""
        items.append(f"<li class=\"finding {finding.severity}\" data-rule=\"{finding.rule}\"><span class=\"severity\">"
                     f"{finding.severity}</span> {where}{escape(finding.sentence)}{frames}{links}{check}</li>\n")
    if not items:
        return ("<h2 id=\"findings\">Findings</h2>\n<p class=\"good\">Nothing wrong found: every rule of "
                "<code>rtusniff stats</code>'s findings passed.</p>\n")
    return f"<h2 id=\"findings\">Findings</h2>\n<ul class=\"findings\">\n{''.join(items)}</ul>\n"


def _provenance(collector: ReportCollector) -> str:
    rows = "".join(f"<tr><th>{escape(label)}</th><td>{_text(label, value)}</td></tr>\n"
                   for label, value in provenance_facts(collector))
    return f"<h2 id=\"provenance\">Provenance</h2>\n<table class=\"facts\">\n{rows}</table>\n"


def _text(label: str, value: str) -> str:
    return f"<code>{escape(value)}</code>" if label in ("SHA-256", "command") else escape(value)


def _summary(collector: ReportCollector) -> str:
    cards = "".join(f"<div class=\"card\"><div class=\"value {grade}\">{escape(value)}</div>"
                    f"<div class=\"label\">{escape(label)}</div></div>\n"
                    for label, value, grade in bus_summary(collector))
    return f"<h2 id=\"bus\">Bus</h2>\n<div class=\"cards\">\n{cards}</div>\n"


def _health(collector: ReportCollector) -> str:
    rows = health_rows(collector)
    if not rows:
        return "<h2 id=\"health\">Slaves</h2>\n<p class=\"muted\">No request or answer of any slave.</p>\n"
    table = _table("health", HEALTH_COLUMNS, [
        (f" data-slave=\"{escape(row.cells['slave'])}\"",
         [(row.cells[key], " ".join(c for c in ("num" if right else "", row.grade if key == "error_rate" else "") if c))
          for key, _, right in HEALTH_COLUMNS])
        for row in rows])
    return ("<h2 id=\"health\">Slaves, worst first</h2>\n<p class=\"muted\">Error rate: exceptions, CRC errors and "
            "timeouts per request. Latency from each request's end to its answer's start.</p>\n" + table)


def _comparison(comparison: Comparison) -> str:
    lines, totals = comparison_facts(comparison)
    columns, rows, verdicts = comparison_rows(comparison)
    facts = "".join(f"<p class=\"muted\">{escape(line)}</p>\n" for line in lines)
    total = "".join(f"<tr><th>{escape(label)}</th><td class=\"num\">{escape(b)}</td><td class=\"num\">{escape(a)}</td>"
                    "</tr>\n" for label, b, a in totals)
    table = _table("comparison", columns, [
        (f" data-verdict=\"{escape(row['verdict'])}\"",
         [(row[key], _verdict_class(key, row[key]) or ("num" if right else "")) for key, _, right in columns])
        for row in rows])
    return (f"<h2 id=\"comparison\">Before and after</h2>\n{facts}<table class=\"facts\"><tr><th></th>"
            f"<th class=\"num\">before</th><th class=\"num\">after</th></tr>\n{total}</table>\n"
            f"<p class=\"muted\">Per slave and function, before→after (latency and poll period in ms); worse: the "
            f"error rate rose by more than half a percentage point or the latency p95 by more than 20 % and 0.5 ms. "
            f"{escape(verdicts)}.</p>\n{table}")


def _verdict_class(key: str, value: str) -> str:
    if key != "verdict":
        return ""
    return {"worse": "bad", "better": "good", "new": "warn", "gone": "warn"}.get(value, "")


def _charts(collector: ReportCollector) -> str:
    width = collector.timeline.width_ns / 1e9
    series = collector.values.series
    left_out = collector.values.series_left_out
    values = ("<h3>Drive values</h3>\n<p class=\"muted\">What the profiles name, per slave: reported (answers) and "
              "sent (writes); the line is each bucket's last value, the pale bar its range."
              + (f" The first {len(series)} series; {left_out} more in <code>rtusniff values</code>." if left_out
                 else "") + "</p>\n<div id=\"value-charts\"></div>\n") if series else ""
    return ("<h2 id=\"over-time\">Over time</h2>\n"
            f"<div class=\"zoom\"><button type=\"button\" id=\"zoom-reset\">whole capture</button>"
            f"<span id=\"zoom-state\">whole capture</span><span>drag across a chart to zoom; each point is a "
            f"bucket of {width:g} s</span></div>\n<div id=\"charts\"></div>\n"
            f"{values}"
            "<noscript><p class=\"muted\">The charts need JavaScript; the tables do not.</p></noscript>\n")


def _state_changes(collector: ReportCollector) -> str:
    values = collector.values
    if not values.changes:
        return ""
    merged = collector.provenance.merged
    rows = "".join(f"<tr>{_capture_cell(change.capture, merged)}<td class=\"num\">{change.index}</td>"
                   f"<td>{escape(utc_text(change.t_ns))}</td><td class=\"num\">{change.slave}</td>"
                   f"<td>{escape(change.code)}</td>"
                   f"<td>{escape(change.before or '(first seen)')}</td><td>{escape(change.after)}</td></tr>\n"
                   for change in values.changes)
    more = (f"<p class=\"muted\">The first {MAX_CHANGES} of {values.changes_total:,} changes; "
            "<code>rtusniff values CAPTURE --changes</code> lists them all.</p>\n"
            if values.changes_total > len(values.changes) else "")
    return (f"<h2 id=\"states\">State changes</h2>\n<table class=\"states\">\n<tr>"
            f"{'<th>file</th>' if merged else ''}<th class=\"num\">#</th>"
            f"<th>time (UTC)</th><th class=\"num\">slave</th><th>code</th><th>from</th><th>to</th></tr>\n"
            f"{rows}</table>\n{more}")


def _capture_cell(capture: str, merged: bool) -> str:
    return f"<td>{escape(capture)}</td>" if merged else ""


def _classes(classes: str) -> str:
    return f' class="{classes}"' if classes else ""


def _anomalies(collector: ReportCollector) -> str:
    log, capture = collector.anomalies, capture_argument(collector)
    found = [kind for kind in KINDS if log.counts[kind]]
    head = ("<h2 id=\"anomalies\">Anomalies</h2>\n<table class=\"anomaly-kinds\">\n<tr><th>kind</th>"
            "<th class=\"num\">frames</th><th>meaning</th></tr>\n")
    rows = "".join(f"<tr data-kind=\"{kind}\"><td><a href=\"#anomaly-{kind}\">{escape(KINDS[kind][0])}</a></td>"
                   f"<td class=\"num\">{log.counts[kind]:,}</td><td>{escape(KINDS[kind][1])}</td></tr>\n"
                   for kind in found)
    if not found:
        return ("<h2 id=\"anomalies\">Anomalies</h2>\n"
                "<p class=\"good\">None: every frame good, every request answered.</p>\n")
    merged = collector.provenance.merged
    sections = [_kind_section(kind, log.counts[kind], log.kept[kind], capture, merged) for kind in found]
    return head + rows + "</table>\n" + "".join(sections)


def _kind_section(kind: str, count: int, kept: list[Anomaly], capture: str, merged: bool) -> str:
    """``merged`` (``--each``): rows name their file, and ``capture`` is ``FILE``."""
    title = KINDS[kind][0]
    shown = f"all {count:,}" if count == len(kept) else f"the first {len(kept):,} of {count:,}"
    opened = " open" if count <= OPEN_UP_TO else ""
    contexts = [a for a in kept if a.with_context]
    blocks = "".join(_context_block(anomaly) for anomaly in contexts)
    listing = _frame_table([a.row for a in kept], focus=None, files=merged)
    return (f"<details class=\"kind\" id=\"anomaly-{kind}\" data-kind=\"{kind}\" data-count=\"{count}\"{opened}>"
            f"<summary>{escape(title)}: {count:,}</summary>\n"
            f"<p class=\"muted\">The first {len(contexts)} with the frames around them; then {shown} as rows. "
            f"<code>rtusniff analyze {escape(capture)} --around INDEX --context 5</code> shows any of them "
            f"in full{' (FILE: the file a row names)' if merged else ''}.</p>\n{blocks}"
            f"<details><summary>{escape(shown)} as rows</summary>\n{listing}</details>\n"
            "</details>\n")


def _context_block(anomaly: Anomaly) -> str:
    row = anomaly.row
    where = f" of {row.capture}" if row.capture else ""
    return (f"<div class=\"context\" data-index=\"{row.index}\"><p class=\"muted\">#{row.index}{escape(where)} at "
            f"{escape(row.time)}</p>\n"
            f"{_frame_table([*anomaly.before, row, *anomaly.after], focus=row.index)}</div>\n")


def _frame_table(rows: list[FrameRow], focus: int | None, *, files: bool = False) -> str:
    def cell(key: str, value: str, right: bool) -> tuple[str, str]:
        return value, "num" if right else "hex" if key == "hex" else "bad" if key == "crc" and value == "BAD" else ""

    columns = ((("capture", "file", False),) if files else ()) + _ROW_COLUMNS
    return _table("frames", columns, [
        (" class=\"focus\"" if row.index == focus else "",
         [cell(key, str(getattr(row, key)), right) for key, _, right in columns])
        for row in rows])


def _table(css: str, columns: Sequence[tuple[str, str, bool]], rows: list[tuple[str, list[tuple[str, str]]]]) -> str:
    """A table that scrolls on its own on a narrow screen: ``columns`` (key, heading,
    right-aligned), ``rows`` of (the row's attributes, each cell's text and classes)."""
    keys = [f"c-{key}" for key, _, _ in columns]  # a class per column: a narrow screen hides some (report.css)
    head = "".join(f"<th{_classes(' '.join(c for c in ('num' if right else '', keys[k]) if c))}>{escape(heading)}</th>"
                   for k, (_, heading, right) in enumerate(columns))
    body = "".join(f"<tr{attributes}>" + "".join(f"<td{_classes(' '.join(c for c in (classes, keys[k]) if c))}>"
                                                  f"{escape(text)}</td>" for k, (text, classes) in enumerate(cells))
                   + "</tr>\n" for attributes, cells in rows)
    return f"<div class=\"scroll\"><table class=\"{css}\">\n<tr>{head}</tr>\n{body}</table></div>\n"
