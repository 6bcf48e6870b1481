"""``rtusniff analyze CAPTURE``: every frame on the wire, as a table or as JSON Lines."""

from __future__ import annotations

import argparse
import os
import sys
from contextlib import ExitStack
from typing import TextIO

from rich.console import Console

from sniffer.commands.common import (
    add_input_format_option,
    add_line_options,
    add_timing_option,
    apply_char_timing,
    effective_timing,
    line_override,
)
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.registry import open_reader
from sniffer.pipeline import MessageView, analyze, effective_line
from sniffer.views.jsonl import JsonlView
from sniffer.views.table import TableView

#: Width of the table when the output is not a terminal (a file, a pipe).
FILE_TABLE_WIDTH = 180


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="split a capture into frames and show them",
        description="Split a capture into frames and show every frame: time, silence before it, "
        "slave, function, role, length, CRC, flags and bytes.",
    )
    parser.add_argument("capture", help="capture file (.log/.txt text, .mcap native), or - for text on stdin")
    parser.add_argument("--format", choices=["table", "jsonl"], default="table", help="output format (default: table)")
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")
    add_line_options(parser)
    add_timing_option(parser)
    add_input_format_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    with ExitStack() as stack:
        out = _open_output(args.output, stack)
        reader = open_reader(args.capture, args.input_format)
        stack.callback(reader.close)
        line = apply_char_timing(effective_line(reader.info, line_override(args), args.capture), args)
        view: MessageView
        if args.format == "jsonl":
            view = JsonlView(out)
        else:
            width = None if out.isatty() or "COLUMNS" in os.environ else FILE_TABLE_WIDTH
            view = TableView(Console(file=out, width=width, highlight=False))
        analyze(reader, args.capture, line, effective_timing(reader.info, args), view)
    return 0


def _open_output(path: str | None, stack: ExitStack) -> TextIO:
    if path is None or path == "-":
        return sys.stdout
    try:
        return stack.enter_context(open(path, "w", encoding="utf-8"))
    except OSError as exc:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from None
