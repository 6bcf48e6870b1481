"""``rtusniff compare BEFORE AFTER``: what changed per slave and function between two captures."""

from __future__ import annotations

import argparse
from contextlib import ExitStack

from decoders.compare import compare
from sniffer.commands.common import (
    add_decoding_options,
    add_force_option,
    add_output_option,
    add_quiet_option,
    add_width_option,
    check_outputs,
    open_output,
    tell_written,
)
from sniffer.commands.counting import counted_capture
from sniffer.views.compare_view import write_comparison
from sniffer.views.layout import terminal_layout


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="two captures side by side: what changed per slave and function (did the fix help?)",
        description="Count both captures as stats does and put them side by side, per slave and function: "
        "requests, error and timeout rates, latency p50/p95/max and poll period, before→after, with a verdict "
        "(worse: the error rate rose by more than half a percentage point or the latency p95 by more than 20 %% "
        "and 0.5 ms; better: the same falls; new, gone, same). The decoding options apply to both captures.",
    )
    parser.add_argument("before", metavar="BEFORE", help="the capture before the change")
    parser.add_argument("after", metavar="AFTER", help="the capture after it")
    parser.add_argument("--format", choices=["table", "json"], default="table", help="output format (default: table)")
    add_output_option(parser)
    add_width_option(parser)
    add_force_option(parser)
    add_decoding_options(parser)
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_outputs([args.output], [args.before, args.after], force=args.force)
    sides = [counted_capture(args, path) for path in (args.before, args.after)]
    with ExitStack() as stack:
        out = open_output(args.output, stack)
        width, colors = terminal_layout(args, out) if args.format == "table" else (None, None)
        write_comparison(out, sides[0], sides[1], compare(sides[0].statistics, sides[1].statistics),
                         as_json=args.format == "json", width=width, colors=colors)
    if args.output not in (None, "-"):
        tell_written(args, [(args.output, f"{args.format}, {args.before} vs {args.after}")])
    return 0
