"""``rtusniff stats CAPTURE``: traffic per slave and function, latencies, errors, bus load."""

from __future__ import annotations

import argparse
from contextlib import ExitStack
from dataclasses import replace
from typing import TextIO

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.stats import Statistics
from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_follow_option,
    add_force_option,
    add_output_option,
    add_quiet_option,
    add_width_option,
    capture_paths,
    check_outputs,
    open_output,
    tell_written,
)
from sniffer.commands.counting import counted_capture
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.library import Capture
from sniffer.many_captures import Tally, add_each_options, capture_files, each_result, jobs_for_each
from sniffer.progress import progress_for, shown
from sniffer.views.compare_view import Side
from sniffer.views.layout import terminal_layout
from sniffer.views.stats_view import StatsView
from sniffer.wording import counted


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "stats",
        help="statistics per slave and function: requests, answers, errors, latency, poll period, bus load",
        description="Count what happened on the bus, per slave and function: requests, responses, exceptions "
        "by code, CRC errors, timeouts, retries, unexpected answers, gap_1_5 and short_idle; latency "
        "min/p50/p95/p99/max and poll period; bus load and totals. On a terminal the table fits its width "
        "(the least needed columns go first); into a pipe or a file every row is one line.",
    )
    add_capture_argument(parser)
    parser.add_argument("--format", choices=["table", "json"], default="table", help="output format (default: table)")
    add_output_option(parser)
    add_width_option(parser)
    add_force_option(parser)
    add_decoding_options(parser)
    add_follow_option(parser)
    add_each_options(parser, "the statistics merged: counts and histograms add up")
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], capture_paths(args), force=args.force, following=args.follow)
    if args.each:
        return _run_each(args)
    with ExitStack() as stack:
        out = open_output(args.output, stack, as_it_goes=args.follow)
        capture = Capture(args, stack)
        view = _view(out, args)
        progress = stack.enter_context(progress_for(args, capture.reader, streaming=False))
        statistics = capture.decode([progress.sink, view])
    if args.output not in (None, "-"):
        tell_written(args, [(args.output, f"{args.format} statistics of {counted(statistics.frames, 'frame')}")])
    return 0


def _view(out: TextIO, args: argparse.Namespace) -> StatsView:
    """The statistics as JSON, or as tables laid out for the terminal ``out`` is."""
    if args.format == "json":
        return StatsView(out, width=None, as_json=True)
    width, colors = terminal_layout(args, out)
    return StatsView(out, width=width, color_system=colors, as_json=False)


def _run_each(args: argparse.Namespace) -> int:
    """``--each``: every capture counted on its own (in a pool), the statistics merged, one table."""
    if args.follow:
        raise RtuSniffError(ErrorKind.USAGE, "--follow follows one capture, --each reads many: give one of them")
    files = capture_files(args.capture)
    merged, first, tally = Statistics(), None, Tally(len(files))
    quiet = argparse.Namespace(**{**vars(args), "quiet": True})  # no progress bars from the pool
    bar = shown(args, streaming=False)
    captures = []
    for side in each_result(files, _counted, quiet, jobs_for_each(args.jobs), tally, show=bar):
        first = first or side
        merged.merge(side.statistics)
        captures.append({"source": side.source, "line": side.line, "timing": side.timing})
    done = tally.done
    with ExitStack() as stack:
        out = open_output(args.output, stack, as_it_goes=args.follow)
        view = _view(out, args)
        if first is not None:
            line = LineSettings.parse(first.line)
            view.start(f"{done} of {len(files)} captures", CaptureInfo(line, TimingQuality(first.timing)), line)
            view.each_capture(captures)
            view.finish(merged)
    if args.output not in (None, "-") and first is not None:
        tell_written(args, [(args.output, f"{args.format} statistics of {merged.frames:,} frames, {done} captures")])
    return tally.exit_code()


def _counted(args: argparse.Namespace) -> Side:
    """One capture of ``--each``, counted (in a process of the pool: what comes back is small)."""
    side = counted_capture(args, args.capture[0])
    return replace(side, statistics=side.statistics.portable())
