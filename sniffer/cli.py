"""``rtusniff``: the command line. ``main(argv) -> exit code``.

Data goes to standard output, errors to standard error as one ``error: …`` line
(the traceback only with ``--debug``); exit codes are listed in :mod:`sniffer.errors`.
"""

from __future__ import annotations

import argparse
import gc
import sys
from collections.abc import Sequence
from importlib.metadata import version

from sniffer.commands import analyze, capture, convert, export, ports, profiles, stats
from sniffer.errors import ErrorKind, RtuSniffError

COMMANDS = [analyze, stats, export, capture, ports, convert, profiles]
INTERRUPTED_EXIT = 130
#: Objects allocated between young-generation collections. Decoding builds millions of
#: short-lived objects next to long-lived caches of decodings; at Python's default (700)
#: the collector walks the caches again and again: 9.9 s instead of 6.0 s for `analyze`
#: of 200 000 frames that are all distinct (benchmarks/bench_stages.py).
GC_YOUNG_THRESHOLD = 100_000


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rtusniff",
        description="Modbus RTU protocol analyzer and passive RS485 bus sniffer.",
    )
    parser.add_argument("--version", action="version", version=f"rtusniff {version('rtusniff')}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of errors")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND", required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    args.command_line = ["rtusniff", *(sys.argv[1:] if argv is None else argv)]
    try:
        result: int = args.run(args)
        return result
    except RtuSniffError as exc:
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return ErrorKind.USAGE.exit_code if exc.kind is ErrorKind.USAGE else exc.kind.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return INTERRUPTED_EXIT
    except BrokenPipeError:
        # The reader of our output (e.g. `head`) has gone; that is not an error.
        sys.stderr.close()
        return 0


def entry_point() -> None:
    sys.exit(main())
