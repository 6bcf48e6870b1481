"""``rtusniff cut CAPTURE -o OUT``: a window of a capture as a small capture that reproduces it."""

from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack, suppress
from dataclasses import replace

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.pipeline import Decoder
from sniffer.commands.common import (
    add_capture_argument,
    add_channel_option,
    add_force_option,
    add_input_format_option,
    add_line_options,
    add_quiet_option,
    add_time_option,
    add_timing_option,
    capture_paths,
    check_outputs,
    close_reader,
    reader_options,
    source_name,
    tell_written,
)
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.capture_cut import (
    SEARCHED_FRAMES,
    Context,
    PastWindow,
    WindowFinder,
    WindowPlace,
    cut_batch,
    reproducing_context,
    window_chunks,
)
from sniffer.exports.outputs import sha256_of
from sniffer.io.chain import open_capture
from sniffer.io.output_files import published_whole
from sniffer.io.registry import format_help, formats_for, open_writer
from sniffer.library import Capture
from sniffer.pipeline import Analysis
from sniffer.selection import EVERYTHING, add_selection_options
from sniffer.views.clock import Clock


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "cut",
        help="a window of a capture as a small capture (--from/--to, --around/--context) that reproduces it",
        description="Write the frames of a window (--from/--to, --around INDEX --context N, --limit N) as a "
        "capture of its own: the same line settings, timing and notes, and a note saying where it came from "
        "(the source's SHA-256, frames, times and byte offsets). The cut follows frame boundaries: never "
        "inside a frame; it takes the few frames of context around the window with which the window decodes "
        "as in the whole capture, and its note says where the window is.",
    )
    add_capture_argument(parser)
    parser.add_argument("-o", "--output", required=True, help="the capture to write (its suffix names the format)")
    parser.add_argument("--output-format", choices=sorted(formats_for("write")),
                        help=f"default: from the suffix. {format_help('write')}")
    add_selection_options(parser)
    add_time_option(parser)
    add_line_options(parser)
    add_timing_option(parser)
    add_input_format_option(parser)
    add_channel_option(parser)
    add_force_option(parser)
    add_quiet_option(parser)
    parser.set_defaults(run=run, profile=[], profile_file=[], response_timeout=None)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], capture_paths(args), force=args.force)
    with ExitStack() as stack:
        capture = Capture(args, stack)
        reader, analysis = capture.reader, capture.analysis
        if not analysis.selection.windowed and analysis.selection.limit is None:
            raise RtuSniffError(ErrorKind.USAGE, "cut needs a window: --from/--to, --around INDEX or --limit N")
        finder = WindowFinder(analysis.selection)
        with suppress(PastWindow):  # the window is complete: the rest need not be read
            capture.decode([finder], analysis=replace(analysis, selection=EVERYTHING))
        info, line, timing = reader.info, analysis.line, analysis.timing
    place = finder.place
    if place.first_index is None:
        missed = finder.missed() or "no frame in the window"
        raise RtuSniffError(ErrorKind.NO_DATA, f"{missed}; nothing to cut", path=source_name(args))
    context, held = _context(args, place, analysis)
    start, end = context.span(place)
    note = _provenance(args, place, context, Clock(args.time))
    edges = place.edges() if not context.reproduces else None
    info = CaptureInfo(line, timing, (*info.notes, note, *([edges] if edges else [])), info.channels,
                       first_index=place.first_index - context.before)
    chunks = 0
    # A cut that stops where reading broke would pass for the window: it appears only whole.
    with published_whole(args.output) as target:
        writer = open_writer(target, info, args.output_format)
        try:
            if held is not None:  # the bytes the search held: no second reading
                batch = cut_batch(held[0], start - held[1], end - held[1], line)
                writer.write_batch(batch)
                chunks = len(batch)
            else:
                second = open_capture(capture_paths(args), args.input_format, reader_options(args))
                try:
                    for batch in window_chunks(second.batches(), (start, end), line):
                        writer.write_batch(batch)
                        chunks += len(batch)
                finally:
                    close_reader(second)
        finally:
            writer.close()
    extra = f", with {context.before} frame(s) before and {context.after} after" if context.before or context.after \
        else ""
    what = (f"frames #{place.first_index}..#{place.last_index} ({place.frames:,}){extra}, "
            f"{end - start:,} bytes of line data in {chunks:,} chunks")
    tell_written(args, [(args.output, what)])
    if edges:
        print(f"warning: {args.output}: {edges}; a window that starts earlier keeps them whole", file=sys.stderr)
    return 0


def _context(args: argparse.Namespace, place: WindowPlace,
             analysis: Analysis) -> tuple[Context, tuple[ChunkBatch, int] | None]:
    """The context with which the cut decodes as the window did in the whole capture
    (:func:`~sniffer.exports.capture_cut.reproducing_context`), and the bytes searched (the
    window with the most context it may take, and where they begin), which the cut is written
    from; none for a window too long to search."""
    if len(place.verdicts) > SEARCHED_FRAMES:
        return Context(reproduces=False), None
    widest = Context(len(place.before), len(place.after)).span(place)
    reader = open_capture(capture_paths(args), args.input_format, reader_options(args))
    try:
        held = ChunkBatch.concat(list(window_chunks(reader.batches(), widest, analysis.line)))
    finally:
        close_reader(reader)
    context = reproducing_context(place, held, widest[0], analysis.line,
                                  lambda: Decoder(analysis.line, analysis.timing,
                                                  response_timeout_ns=analysis.response_timeout_ns))
    return context, (held, widest[0])


def _provenance(args: argparse.Namespace, place: WindowPlace, context: Context, clock: Clock) -> str:
    digests = " ".join(sha256_of(path) for path in capture_paths(args))
    assert place.first_index is not None and place.last_index is not None
    start, end = context.span(place)
    held = (f"; with {context.before} frame(s) before it and {context.after} after, so that it decodes as in the "
            "whole capture" if context.before or context.after else "")
    return (f"cut from {source_name(args)} (sha256 {digests}): frames #{place.first_index}..#{place.last_index} "
            "(numbered as there), "
            f"{_moment(clock, place.t_first_ns)} to {_moment(clock, place.t_last_ns)} ({clock.zone}), bytes "
            f"{start:,}..{end:,} of its line data{held}")


def _moment(clock: Clock, t_ns: int) -> str:
    return f"{clock.date(t_ns)}.{t_ns % 1_000_000_000 // 1000:06d}"
