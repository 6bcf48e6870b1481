"""``rtusniff stats CAPTURE``: traffic per slave and function, latencies, errors, bus load."""

from __future__ import annotations

import argparse
import os
from contextlib import ExitStack

from rich.console import Console

from sniffer.commands.analyze import FILE_TABLE_WIDTH
from sniffer.commands.common import add_decoding_options, add_force_option, check_outputs, open_analysis, open_output
from sniffer.pipeline import analyze
from sniffer.views.stats_view import StatsView


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "stats",
        help="statistics per slave and function: requests, answers, errors, latency, poll period, bus load",
        description="Count what happened on the bus, per slave and function: requests, responses, exceptions "
        "by code, CRC errors, timeouts, retries, unexpected answers, gap_1_5 and short_idle; latency "
        "min/p50/p95/p99/max and poll period; bus load and totals.",
    )
    parser.add_argument("capture", help="capture file (.log/.txt text, .mcap native), or - for text on stdin")
    parser.add_argument("--format", choices=["table", "json"], default="table", help="output format (default: table)")
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")
    add_force_option(parser)
    add_decoding_options(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], [args.capture], force=args.force)
    with ExitStack() as stack:
        out = open_output(args.output, stack)
        reader, analysis = open_analysis(args, stack)
        width = None if out.isatty() or "COLUMNS" in os.environ else FILE_TABLE_WIDTH
        view = StatsView(out, Console(file=out, width=width, highlight=False), as_json=args.format == "json")
        analyze(reader, args.capture, analysis, [view])
    return 0
