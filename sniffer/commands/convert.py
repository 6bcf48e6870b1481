"""``rtusniff convert IN OUT``: between capture formats, losslessly."""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

from sniffer.commands.common import add_input_format_option, add_line_options, close_reader, line_override
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.registry import all_formats, open_reader, open_writer


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "convert",
        help="convert a capture between formats (text .log <-> native .mcap)",
        description="Copy a capture into another format: every chunk with its time, the line "
        "settings, the timing quality and the notes.",
    )
    parser.add_argument("input", help="capture to read, or - for text on stdin")
    parser.add_argument("output", help="capture to write, or - for text on stdout")
    add_input_format_option(parser)
    parser.add_argument("--output-format", choices=sorted(all_formats()), help="default: from the suffix")
    add_line_options(parser)
    parser.add_argument("--force", action="store_true", help="overwrite an existing output file")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.output != "-" and os.path.exists(args.output) and not args.force:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists; add --force to overwrite it", path=args.output)
    if args.output != "-" and os.path.abspath(args.output) == os.path.abspath(args.input):
        raise RtuSniffError(ErrorKind.USAGE, "input and output are the same file", path=args.output)
    reader = open_reader(args.input, args.input_format)
    try:
        info = reader.info
        override = line_override(args)
        if override is not None:
            info = replace(info, line=override)
        writer = open_writer(args.output, info, args.output_format)
        try:
            for batch in reader.batches():
                writer.write_batch(batch)
            writer.add_notes(reader.late_notes)
        except BaseException:
            writer.close()
            if args.output != "-":
                # A copy that stops where the input broke would pass for a whole capture.
                os.remove(args.output)
            raise
        writer.close()
    finally:
        close_reader(reader)
    return 0
