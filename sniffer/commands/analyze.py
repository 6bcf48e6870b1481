"""``rtusniff analyze CAPTURE``: every frame on the wire, as a table or as JSON Lines."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from contextlib import ExitStack
from typing import TextIO

from decoders.decoded_batch import AnnotatedBatch
from decoders.message import MessageBatch
from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_filter_option,
    add_follow_option,
    add_force_option,
    add_jobs_option,
    add_output_option,
    add_quiet_option,
    add_width_option,
    capture_paths,
    check_outputs,
    open_output,
    replay_speed,
    tell_written,
)
from sniffer.decoding_process import decoding_jobs
from sniffer.exports.streams import add_stream_options, check_streams, stream_sinks
from sniffer.library import Capture
from sniffer.progress import progress_for
from sniffer.sinks import Sink
from sniffer.views.clock import Clock
from sniffer.views.jsonl import JsonlView
from sniffer.views.layout import terminal_layout
from sniffer.views.registers import add_register_options, summary_reader
from sniffer.views.table import PlainTableView, TableView
from sniffer.wording import counted


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="split a capture into frames, decode and pair them, and show them",
        description="Show every frame of a capture: time, silence before it, slave, function, role, "
        "the request it answers and its latency, length, CRC, flags, decoded summary and bytes. "
        "On a terminal the table fits its width; into a pipe or a file every frame is one line.",
    )
    add_capture_argument(parser)
    parser.add_argument("--format", choices=list(FORMATS), default="table", help="output format (default: table)")
    add_output_option(parser)
    add_force_option(parser)
    add_filter_option(parser)
    view = parser.add_argument_group("the table")
    view.add_argument("--hex", action=argparse.BooleanOptionalAction, default=None,
                      help="show the frame's bytes (default: on a terminal when there is room; not into a pipe)")
    add_width_option(view, "frame")
    add_register_options(view)
    add_decoding_options(parser)
    add_follow_option(parser)
    add_stream_options(parser, replay=True)
    add_jobs_option(parser)
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def table_sink(out: TextIO, args: argparse.Namespace) -> Sink:
    """The table: laid out for the terminal ``out`` is (its width and colours), else one line a frame."""
    width, colors = terminal_layout(args, out)
    if width is None:
        return PlainTableView(out, clock=Clock(args.time), hex_shown=args.hex, summary_of=summary_reader(args))
    return TableView(out, width=width, color_system=colors, clock=Clock(args.time),
                     hex_shown=args.hex, summary_of=summary_reader(args))


def jsonl_sink(out: TextIO, args: argparse.Namespace) -> Sink:
    return JsonlView(out)


#: ``--format`` → the sink writing it to the output; adding a format is a sink plus one line here.
FORMATS: dict[str, Callable[[TextIO, argparse.Namespace], Sink]] = {"table": table_sink, "jsonl": jsonl_sink}


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], capture_paths(args), force=args.force, following=args.follow)
    check_streams(args)
    jobs = decoding_jobs(args.jobs, follow=args.follow, paced=replay_speed(args) is not None)
    with ExitStack() as stack:
        out = open_output(args.output, stack, as_it_goes=args.follow)
        capture = Capture(args, stack)
        sink = FORMATS[args.format](out, args)
        streams = stream_sinks(args, replay=True)
        for stream in streams:
            stack.callback(stream.close)
        # Following: each batch reaches a pipe (| jq, | grep) as it is decoded.
        flushing = [FlushEachBatch(out)] if args.follow else []
        progress = stack.enter_context(progress_for(args, capture.reader, streaming=args.output in (None, "-")))
        statistics = capture.decode([progress.sink, sink, *flushing, *streams], jobs=jobs)
    if args.output not in (None, "-"):
        tell_written(args, [(args.output, f"{args.format}, {counted(shown_frames(sink, statistics.frames), 'frame')}")])
    return 0


class FlushEachBatch(Sink):
    """Flushes the output after each batch the view wrote: after its ``messages`` and, for a
    view that writes once its ``prepare`` is back (tables to a pipe, JSONL), after that."""

    wants_messages = True

    def __init__(self, out: TextIO) -> None:
        self._out = out
        self.prepare = _nothing

    def messages(self, batch: AnnotatedBatch) -> None:
        self._out.flush()

    def prepared(self, value: None) -> None:
        self._out.flush()


def _nothing(batch: MessageBatch) -> None:
    """``prepare`` of a sink that has nothing to prepare but wants ``prepared`` called."""


def shown_frames(sink: Sink, frames: int) -> int:
    return getattr(sink, "shown", frames)
