"""The Markdown report (``report --format md``): provenance, the bus, the health table and the
first anomalies of each kind with their hex, to paste into a GitHub, GitLab or Jira ticket.

A pasted report renders only what rtusniff wrote: every text that came from elsewhere (file
names, notes, FC 43 device identification, a summary of a frame's bytes) is escaped by
:func:`_text` (each character that could start HTML, an image, a link, emphasis or a table cell
gets a backslash; line breaks become spaces), and frames go in a fence longer than any run of
backticks they hold.
"""

from __future__ import annotations

import re
from typing import TextIO

from decoders.anomalies import KINDS
from sniffer.report.anomalies import Anomaly, FrameRow
from sniffer.report.collect import Comparison, ReportCollector
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

#: Anomalies of each kind written with the frames around them.
EXAMPLES = 3


def write_markdown(out: TextIO, collector: ReportCollector, comparison: Comparison | None = None) -> None:
    lines = [f"# {_text(report_title(collector))}", "", *_findings(collector), "## Bus", ""]
    lines += [f"- {label}: **{_text(value)}**" if grade == "bad" else f"- {label}: {_text(value)}"
              for label, value, grade in bus_summary(collector)]
    lines += ["", *_health(collector), *(_comparison(comparison) if comparison else []), *_anomalies(collector)]
    lines += ["", "## Provenance", "", "| | |", "|---|---|"]
    lines += [f"| {label} | {_cell(value, code=label in ('SHA-256', 'command'))} |"
              for label, value in provenance_facts(collector)]
    out.write("\n".join(lines) + "\n")


def _findings(collector: ReportCollector) -> list[str]:
    """What is wrong, first: a line each, linking to the anomalies that hold its frames."""
    if not collector.findings:
        return ["## Findings", "", "Nothing wrong found.", ""]
    lines = ["## Findings", ""]
    for capture, finding in collector.findings:
        frames = f" (frames {', '.join(f'#{i}' for i in finding.frames)})" if finding.frames else ""
        counts = collector.anomalies.counts
        links = "".join(f" → [{KINDS[kind][0]}](#{_anchor(_kind_heading(kind, counts[kind]))})"
                        for kind in finding.kinds if counts[kind])
        where = f"{_text(capture)}: " if capture else ""
        lines.append(f"- **{finding.severity}** {where}{_text(finding.sentence)}{frames}{links}")
        if finding.causes:
            lines.append(f"  check: {_text('; '.join(finding.causes))}")
    return [*lines, ""]


def _kind_heading(kind: str, count: int) -> str:
    return f"{KINDS[kind][0]}: {count:,}"


def _anchor(heading: str) -> str:
    """The anchor GitHub and GitLab give a heading (``### CRC error: 1,234``: ``crc-error-1234``)."""
    return re.sub(r"[^a-z0-9 -]", "", heading.lower()).replace(" ", "-")


def _health(collector: ReportCollector) -> list[str]:
    rows = health_rows(collector)
    if not rows:
        return ["## Slaves", "", "No request or answer of any slave.", ""]
    lines = ["## Slaves, worst first", "",
             "Error rate: exceptions, CRC errors and timeouts per request.", "",
             "| " + " | ".join(heading for _, heading, _ in HEALTH_COLUMNS) + " |",
             "|" + "|".join("---:" if right else "---" for _, _, right in HEALTH_COLUMNS) + "|"]
    for row in rows:
        cells = [_cell(row.cells[key]) for key, _, _ in HEALTH_COLUMNS]
        if row.grade == "bad":
            cells[[key for key, _, _ in HEALTH_COLUMNS].index("error_rate")] = f"**{_cell(row.cells['error_rate'])}**"
        lines.append("| " + " | ".join(cells) + " |")
    return [*lines, ""]


def _comparison(comparison: Comparison) -> list[str]:
    lines, totals = comparison_facts(comparison)
    columns, rows, verdicts = comparison_rows(comparison)
    text = ["## Before and after", "", *[f"- {_cell(line)}" for line in lines], "",
            "| | before | after |", "|---|---:|---:|", *[f"| {label} | {b} | {a} |" for label, b, a in totals], "",
            "Per slave and function, before→after (latency and poll period in ms):", "",
            "| " + " | ".join(heading for _, heading, _ in columns) + " |",
            "|" + "|".join("---:" if right else "---" for _, _, right in columns) + "|"]
    for row in rows:
        cells = [_cell(row[key]) for key, _, _ in columns]
        text.append("| " + " | ".join(f"**{c}**" if c == "worse" else c for c in cells) + " |")
    return [*text, "", f"{verdicts}.", ""]


def _anomalies(collector: ReportCollector) -> list[str]:
    log = collector.anomalies
    found = [kind for kind in KINDS if log.counts[kind]]
    if not found:
        return ["## Anomalies", "", "None: every frame good, every request answered."]
    capture = capture_argument(collector)
    lines = ["## Anomalies", "", "| kind | frames | meaning |", "|---|---:|---|"]
    lines += [f"| {KINDS[kind][0]} | {log.counts[kind]:,} | {KINDS[kind][1]} |" for kind in found]
    lines += ["", f"Any of them in full: {_code(f'rtusniff analyze {capture} --around INDEX --context 5')}"
              + (" (FILE: the file an example names)." if collector.provenance.merged else "."), ""]
    for kind in found:
        examples = [anomaly for anomaly in log.kept[kind] if anomaly.with_context][:EXAMPLES]
        lines += [f"### {_kind_heading(kind, log.counts[kind])}", ""]
        for anomaly in examples:
            lines += _example(anomaly)
    return lines


def _example(anomaly: Anomaly) -> list[str]:
    row = anomaly.row
    rows = [*anomaly.before, row, *anomaly.after]
    where = f" of {_text(row.capture)}" if row.capture else ""
    lines = [_frame_line(frame, focus=frame.index == row.index) for frame in rows]
    fence = "`" * max([3, *(len(run) + 1 for line in lines for run in _BACKTICKS.findall(line))])
    return [f"#{row.index}{where} at {row.time} UTC:", "", f"{fence}text", *lines, fence, ""]


def _frame_line(row: FrameRow, *, focus: bool) -> str:
    fields = [f"#{row.index}", row.time.split(" ")[1], f"slave {row.slave or '-'}", f"fc {row.function or '-'}",
              row.role, f"CRC {row.crc}" if row.crc else "", row.flags, row.hex]
    text = "  ".join(field for field in fields if field)
    return _one_line(f"{'>' if focus else ' '} {text}  | {row.summary}")


_BACKTICKS = re.compile("`+")
#: Characters that start Markdown (CommonMark, GFM, GitHub's math) where they stand in a line;
#: ``_`` inside a word starts nothing (GFM), so ``make_samples.py`` stays as it is.
_ACTIVE = re.compile(r"([\\`*\[\]<>!|~&$#]|(?<![A-Za-z0-9])_|_(?![A-Za-z0-9]))")
_LINE_BREAKS = re.compile(r"[\x00-\x1f\x7f\u2028\u2029\x85]")


def _one_line(text: str) -> str:
    return _LINE_BREAKS.sub(" ", text)


def _text(text: str) -> str:
    """Text from elsewhere, rendered as the characters it holds and nothing else."""
    return _ACTIVE.sub(r"\\\1", _one_line(text))


def _code(text: str) -> str:
    """A code span: nothing in it renders; a backtick would end it, and ``|`` a table cell."""
    return f"`{_one_line(text).replace('`', chr(39)).replace('|', chr(92) + '|')}`"


def _cell(text: str, *, code: bool = False) -> str:
    return _code(text) if code else _text(text)
