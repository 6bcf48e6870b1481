"""``rtusniff convert IN OUT``: between capture formats, losslessly."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace

from sniffer.commands.common import (
    add_channel_option,
    add_input_format_option,
    add_line_options,
    add_quiet_option,
    check_outputs,
    close_reader,
    human_size,
    line_override,
)
from sniffer.io.base import ReaderOptions
from sniffer.io.output_files import published_whole
from sniffer.io.registry import format_help, formats_for, open_reader, open_writer
from sniffer.progress import progress_for


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
    parser.add_argument("--output-format", choices=sorted(formats_for("write")),
                        help=f"default: from the suffix. {format_help('write')}")
    add_line_options(parser)
    add_channel_option(parser)
    parser.add_argument("--force", action="store_true", help="overwrite an existing output file")
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], [args.input], force=args.force)
    override = line_override(args)
    reader = open_reader(args.input, args.input_format,
                         ReaderOptions(line=override, channels=tuple(args.channel or ())))
    try:
        info = reader.info
        if override is not None:
            info = replace(info, line=override)
        chunks = size = 0
        # A copy that stops where the input broke would pass for a whole capture: it appears only whole.
        with published_whole(args.output) as target:
            writer = open_writer(target, info, args.output_format)
            progress = progress_for(args, reader, streaming=args.output == "-", path=args.input)
            try:
                with progress:
                    for batch in reader.batches():
                        writer.write_batch(batch)
                        progress.sink.chunks(batch)
                        chunks += len(batch)
                        size += len(batch.data)
                writer.add_notes(reader.late_notes)
            finally:
                writer.close()
    finally:
        close_reader(reader)
    if args.quiet:
        return 0
    target = "standard output" if args.output == "-" else f"{args.output} ({human_size(os.path.getsize(args.output))})"
    print(f"wrote {chunks:,} chunks, {size:,} bytes of line data to {target}", file=sys.stderr)
    return 0
