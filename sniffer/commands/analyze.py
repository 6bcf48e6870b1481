"""``rtusniff analyze CAPTURE``: every frame on the wire, as a table or as JSON Lines."""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import replace
from typing import TextIO

from rich.console import Console

from sniffer.commands.common import (
    add_decoding_options,
    add_force_option,
    add_jobs_option,
    check_outputs,
    open_analysis,
    open_output,
)
from sniffer.decoding_process import decoding_jobs
from sniffer.filters import parse_filters
from sniffer.pipeline import analyze
from sniffer.sinks import Sink
from sniffer.views.jsonl import JsonlView
from sniffer.views.table import TableView

#: Width of the table when the output is not a terminal (a file, a pipe).
FILE_TABLE_WIDTH = 200


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="split a capture into frames, decode and pair them, and show them",
        description="Show every frame of a capture: time, silence before it, slave, function, role, "
        "the request it answers, length, CRC, flags, decoded summary and bytes.",
    )
    parser.add_argument("capture", help="capture file (.log/.txt text, .mcap native), or - for text on stdin")
    parser.add_argument("--format", choices=list(FORMATS), default="table", help="output format (default: table)")
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")
    add_force_option(parser)
    parser.add_argument(
        "--filter",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="show only matching frames: slave=N, function=N, role=NAME, flag=NAME; repeat a key for "
        "alternatives, combine keys to narrow (the JSONL summary still covers every frame)",
    )
    add_decoding_options(parser)
    add_jobs_option(parser)
    parser.set_defaults(run=run)


def table_sink(out: TextIO) -> Sink:
    """The table, as wide as the terminal, or ``FILE_TABLE_WIDTH`` into a file or a pipe."""
    width = None if out.isatty() or "COLUMNS" in os.environ else FILE_TABLE_WIDTH
    return TableView(Console(file=out, width=width, highlight=False))


#: ``--format`` → the sink writing it to the output; adding a format is a sink plus one line here.
FORMATS: dict[str, Callable[[TextIO], Sink]] = {"table": table_sink, "jsonl": JsonlView}


def run(args: argparse.Namespace) -> int:
    keep = parse_filters(args.filter)
    check_outputs([args.output], [args.capture], force=args.force)
    with ExitStack() as stack:
        out = open_output(args.output, stack)
        reader, analysis = open_analysis(args, stack)
        if not keep.empty:
            analysis = replace(analysis, keep=keep)
        sink = FORMATS[args.format](out)
        analyze(reader, args.capture, analysis, [sink], jobs=decoding_jobs(args.jobs))
    return 0
