"""``rtusniff report CAPTURE -o report.html``: evidence for a bug report, in one file anyone can open."""

from __future__ import annotations

import argparse
import shlex
import sys
from contextlib import ExitStack
from pathlib import Path

from decoders.compare import compare
from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_force_option,
    add_jobs_option,
    add_quiet_option,
    capture_paths,
    check_outputs,
    open_output,
    source_name,
    tell_written,
)
from sniffer.commands.counting import counted_capture
from sniffer.decoding_process import decoding_jobs
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.output_files import published_whole
from sniffer.library import Capture
from sniffer.many_captures import Tally, add_each_options, capture_files, each_result, jobs_for_each
from sniffer.progress import progress_for, shown
from sniffer.report.collect import Comparison, Provenance, ReportCollector, source_file
from sniffer.report.html import write_html
from sniffer.report.markdown import write_markdown
from sniffer.tool_version import version_number
from sniffer.views.compare_view import Side
from sniffer.wording import counted

WRITERS = {"html": write_html, "md": write_markdown}


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "report",
        help="a report to attach to a bug report: one self-contained HTML file, or Markdown for a ticket",
        description="Write what a capture shows as evidence: provenance (file, size, SHA-256, times, line, "
        "timing, profiles, this command), the bus (load, errors), the slaves' health worst first (requests, "
        "answers, exceptions by code, CRC errors, timeouts, retries, latency p50/p95/max, poll period), charts "
        "over time (bus load, anomalies, latency, drive values; drag to zoom) with the latency distribution per "
        "slave, state changes, and every anomaly by kind with the frames around the first ones (hex, decoded "
        "text, a damaged answer's bytes against its good retry). The HTML needs no network and no other file; "
        "--format md is a summary to paste into GitHub, GitLab or Jira.",
    )
    add_capture_argument(parser)
    parser.add_argument("--format", choices=list(WRITERS),
                        help="html (default) or md; default from the -o suffix (.md: md)")
    parser.add_argument("-o", "--output", help="the file to write (standard output: -, or leave out into a pipe)")
    parser.add_argument("--baseline", metavar="BEFORE",
                        help="an earlier capture to compare with, as 'rtusniff compare BEFORE CAPTURE' does: a "
                        "section 'before and after' per slave and function (read whole, with the same decoding "
                        "options)")
    add_force_option(parser)
    add_decoding_options(parser)
    add_jobs_option(parser)
    add_each_options(parser, "one report of them all: counts and histograms add up, charts and state changes "
                     "join in the order named, anomalies keep the first of each kind with their file")
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def report_format(args: argparse.Namespace) -> str:
    if args.format:
        chosen: str = args.format
        return chosen
    return "md" if args.output and Path(args.output).suffix.lower() in (".md", ".markdown") else "html"


def run(args: argparse.Namespace) -> int:
    kind = report_format(args)
    if args.output is None and kind == "html" and sys.stdout.isatty():
        raise RtuSniffError(ErrorKind.USAGE, "report: an HTML report is a file to open in a browser; "
                            "give -o report.html (or --format md to read it here)")
    paths = capture_files(args.capture) if args.each else capture_paths(args)
    check_outputs([args.output], [*paths, *([args.baseline] if args.baseline else [])], force=args.force)
    tally = Tally(len(paths))
    if args.each:
        collector = _gathered_each(args, paths, tally)
        if collector is None:
            return tally.exit_code()
    else:
        collector = _gathered(args, paths, jobs=decoding_jobs(args.jobs))
    comparison = _comparison(args, collector) if args.baseline else None
    # Written only once everything is read: a capture that fails leaves no half report behind.
    with published_whole(args.output or "-") as target, ExitStack() as stack:
        WRITERS[kind](open_output(target, stack, as_it_goes=True), collector, comparison)
    if args.output not in (None, "-"):
        captures = f", {len(collector.provenance.files)} captures" if args.each else ""
        frames = counted(collector.statistics.frames, "frame")
        tell_written(args, [(args.output, f"{kind} report of {frames}{captures}")])
    return tally.exit_code()


def _gathered(args: argparse.Namespace, paths: list[str], jobs: int, *, part: bool = False) -> ReportCollector:
    """What the report shows of ``paths``, read as one capture (``part``: of ``--each``)."""
    collector = ReportCollector(_provenance(args, paths), part=part)
    with ExitStack() as stack:
        capture = Capture(args, stack)
        progress = stack.enter_context(progress_for(args, capture.reader, streaming=False))
        capture.decode([progress.sink, collector], jobs=jobs)
    return collector


def _gathered_each(args: argparse.Namespace, paths: list[str], tally: Tally) -> ReportCollector | None:
    """``--each``: every capture gathered on its own (in a pool), merged in the order named;
    ``None`` when every capture failed."""
    one = argparse.Namespace(**{**vars(args), "each": False, "quiet": True})  # no progress bars from the pool
    merged = ReportCollector(_provenance(args, []))
    bar = shown(args, streaming=False)
    for part in each_result(paths, _gathered_one, one, jobs_for_each(args.jobs), tally, show=bar):
        merged.merge(part)
    return merged if tally.done else None


def _gathered_one(args: argparse.Namespace) -> ReportCollector:
    """One capture of ``--each`` (in a process of the pool: one process decodes it)."""
    return _gathered(args, args.capture, jobs=1, part=True).portable()


def _provenance(args: argparse.Namespace, paths: list[str]) -> Provenance:
    return Provenance(files=[source_file(path) for path in paths], command=shlex.join(args.command_line),
                      tool_version=version_number(), profiles=list(args.profile), window=_window(args))


def _comparison(args: argparse.Namespace, collector: ReportCollector) -> Comparison:
    whole = argparse.Namespace(**{**vars(args), "start": None, "stop": None, "around": None, "limit": None})
    before = counted_capture(whole, args.baseline)
    p = collector.provenance
    after = Side(source_name(args), p.line, p.timing, collector.statistics)
    return Comparison(source_file(args.baseline), before, after, compare(before.statistics, after.statistics))


def _window(args: argparse.Namespace) -> str:
    parts = [f"{flag} {value}" for flag, value in (("--from", args.start), ("--to", args.stop),
                                                  ("--around", args.around), ("--context", args.context),
                                                  ("--limit", args.limit)) if value is not None]
    return " ".join(parts)
