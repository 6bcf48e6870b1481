"""``rtusniff values CAPTURE``: every value a slave reported or was written, over time."""

from __future__ import annotations

import argparse
from contextlib import ExitStack

from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_filter_option,
    add_force_option,
    add_jobs_option,
    add_output_option,
    add_quiet_option,
    capture_paths,
    check_outputs,
    open_output,
    tell_written,
)
from sniffer.decoding_process import decoding_jobs
from sniffer.encoding.value_rows import ValueChoice
from sniffer.library import Capture
from sniffer.progress import progress_for
from sniffer.views.values import ValuesView


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "values",
        help="every value a slave reported or was written, over time (CSV or JSON Lines)",
        description="Every register or coil value the capture carries: the values slaves reported in their "
        "answers and the values masters wrote, with time, slave, address, the profile's code, name and unit, "
        "the scaled value and whether it is valid (a good answer; a write its slave accepted). One row per "
        "value (long form), or with --wide one row per frame and a column per parameter.",
    )
    add_capture_argument(parser)
    parser.add_argument("--slave", type=int, action="append", metavar="N", help="only this slave (repeatable)")
    parser.add_argument("--param", action="append", metavar="CODE|ADDRESS",
                        help="only this parameter: a profile code (ETA, LFR) or a register address (repeatable)")
    parser.add_argument("--changes", action="store_true",
                        help="keep a value only when it differs from the last one of its slave, address and kind")
    parser.add_argument("--wide", action="store_true",
                        help="one row per frame, a column per parameter (SLAVE:CODE); held in memory until the end")
    parser.add_argument("--format", choices=["csv", "jsonl"], default="csv", help="output format (default: csv)")
    add_output_option(parser)
    add_force_option(parser)
    add_filter_option(parser)
    add_decoding_options(parser)
    add_jobs_option(parser)
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], capture_paths(args), force=args.force)
    choice = ValueChoice(frozenset(args.slave or ()), frozenset(args.param or ()), args.changes)
    with ExitStack() as stack:
        out = open_output(args.output, stack)
        capture = Capture(args, stack)
        view = ValuesView(out, choice, as_json=args.format == "jsonl", wide=args.wide, time_mode=args.time)
        progress = stack.enter_context(progress_for(args, capture.reader, streaming=args.output in (None, "-")))
        capture.decode([progress.sink, view], jobs=decoding_jobs(args.jobs))
    if args.output not in (None, "-"):
        tell_written(args, [(args.output, f"{args.format}, {view.shown:,} values")])
    return 0
