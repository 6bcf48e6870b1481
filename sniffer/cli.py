"""``rtusniff``: the command line. ``main(argv) -> exit code``.

Data goes to standard output, errors to standard error as one ``error: …`` line
(the traceback only with ``--debug``); exit codes are listed in :mod:`sniffer.errors`.
"""

from __future__ import annotations

import argparse
import errno
import gc
import importlib
import importlib.abc
import re
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any, NoReturn

from sniffer.allocator import keep_freed_memory
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.output_files import allow_replacing
from sniffer.stopping import INTERRUPTED, TERMINATED, TerminatedError, restore_signals, terminate_raises
from sniffer.tool_version import tool_version

#: The commands, in the order ``--help`` lists them: each a module of :mod:`sniffer.commands` with
#: ``add_parser``. A command run is parsed by its own parser alone, and only its module imported
#: (the others' imports would add to every command's start; ``python -X importtime`` shows it).
COMMAND_NAMES = ("analyze", "stats", "report", "values", "compare", "cut", "export", "capture", "ports",
                 "convert", "profiles", "wireshark")
#: Errors that only writing raises: a full disk, a quota, a file too large.
WRITE_FAILURES = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
#: Objects allocated between young-generation collections. Decoding builds millions of
#: short-lived objects next to long-lived caches of decodings; at Python's default (700)
#: the collector walks the caches again and again (``benchmarks/bench_stages.py`` shows it on
#: frames that are all distinct). Lower, frames named by a profile, whose caches churn (objects
#: made in one batch, freed in a later one), still set off young and middle collections; at this
#: threshold none, with the same peak RSS (gc callbacks, analyze and export --mcap/--parquet).
GC_YOUNG_THRESHOLD = 500_000


class _VersionAction(argparse.Action):
    """``--version``: the version is read only when asked for (see :mod:`sniffer.tool_version`)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        print(tool_version())
        parser.exit()


class OneLineParser(argparse.ArgumentParser):
    """A wrong argument is one line naming the command and where its options are listed (not
    the whole usage, and a command's own name for a command's option); exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(ErrorKind.USAGE.exit_code, f"error: {self.prog}: {message} ('{self.prog} --help' lists the "
                  "options)\n")


def command_module(name: str) -> ModuleType:
    """The module of the command ``name`` (one of :data:`COMMAND_NAMES`)."""
    return importlib.import_module(f"sniffer.commands.{name}")


def build_parser(command: str | None = None, kind: type[OneLineParser] | None = None) -> argparse.ArgumentParser:
    """The command line's parser: of every command, or of ``command`` alone (the one run);
    ``kind``: its class and its commands' (the library's raises its errors)."""
    parser = (kind or OneLineParser)(
        prog="rtusniff",
        description="Modbus RTU protocol analyzer and passive RS485 bus sniffer.",
        epilog="'rtusniff COMMAND --help' tells a command's options; exit codes are listed in the README.",
    )
    parser.add_argument("--version", action=_VersionAction, nargs=0, help="show the version and exit")
    parser.add_argument("--debug", action="store_true", help="show the traceback of errors")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND")
    for name in COMMAND_NAMES if command is None else (command,):
        command_module(name).add_parser(subparsers)
    _debug_after(subparsers)
    return parser


def _debug_after(subparsers: argparse._SubParsersAction[Any]) -> None:
    """``--debug`` also after a command and an action (`rtusniff profiles draft --debug X`);
    SUPPRESS keeps the top level's value."""
    for subparser in subparsers.choices.values():
        subparser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                               help="show the traceback of errors")
        for action in subparser._actions:
            if isinstance(action, argparse._SubParsersAction):
                _debug_after(action)


#: ``--line 19200 8E1``: a baud rate and a character format, written as two words.
_BAUD = re.compile(r"^\d+$")
#: Anything shaped like a character format (``8E1``, also a wrong one such as ``8Q1``: the
#: line-settings parser then says what is wrong with it).
_CHARACTER_FORMAT = re.compile(r"^\d[A-Za-z]\d(\.\d)?$")


def joined_line_settings(argv: Sequence[str]) -> list[str]:
    """``--line BAUD FORMAT`` as one argument, so that ``--line`` takes exactly one value and
    never swallows the capture name that follows it (``--line 19200 8E1 cap.log``)."""
    joined: list[str] = []
    position = 0
    while position < len(argv):
        word = argv[position]
        following = argv[position + 1 : position + 3]
        if (word == "--line" and len(following) == 2 and _BAUD.match(following[0])
                and _CHARACTER_FORMAT.match(following[1])):
            joined += [word, " ".join(following)]
            position += 3
            continue
        joined.append(word)
        position += 1
    return joined


def main(argv: Sequence[str] | None = None) -> int:
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    keep_freed_memory()
    given = list(sys.argv[1:] if argv is None else argv)
    if given[:1] == ["--version"]:  # as the parser would say it, without every command's modules
        print(tool_version())
        return 0
    command = _command_in(given)
    parser = build_parser(command)
    args, extra = parser.parse_known_args(joined_line_settings(given))
    if extra:
        # Left over after the command's own parser: its error, with its name (not the top level's).
        _deepest(parser, given).error(f"unrecognized arguments: {' '.join(extra)}")
    if not hasattr(args, "run"):
        parser.print_help()
        return 0
    args.command_line = ["rtusniff", *given]
    allow_replacing([])  # nothing may be replaced until a command's --force says which files
    previous = terminate_raises()
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
        return INTERRUPTED
    except TerminatedError:
        print("terminated", file=sys.stderr)
        return TERMINATED
    except BrokenPipeError:
        # The reader of our output (e.g. `head`) has gone; that is not an error.
        sys.stderr.close()
        return 0
    except OSError as exc:
        if exc.errno not in WRITE_FAILURES or args.debug:
            raise
        # Standard output on a full disk (or /dev/full): the files rtusniff opens say their own name.
        print(f"error: cannot write the output: {exc.strerror}", file=sys.stderr)
        return ErrorKind.OUTPUT_FAILED.exit_code
    finally:
        restore_signals(previous)


def _deepest(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The parser of the (sub)command ``argv`` names, as deep as its words go (``wireshark setup``)."""
    for word in (word for word in argv if not word.startswith("-")):
        commands = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
        if not commands or word not in commands[0].choices:
            break
        parser = commands[0].choices[word]
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The command ``argv`` runs (its first word that is no option), if it names one; ``None``:
    no command, or a wrong one, which the parser of every command tells."""
    first = next((word for word in argv if not word.startswith("-")), None)
    return first if first in COMMAND_NAMES else None


def entry_point() -> None:
    _without_pandas()
    code = main()
    # The interpreter's last collections, as it exits, walk every object left (the modules of
    # numpy and pyarrow, profiles, caches), a noticeable wait once everything is written and
    # closed. Frozen, they are left to the process's end.
    gc.freeze()
    sys.exit(code)


def _without_pandas() -> None:
    """pyarrow imports pandas, where it is installed, at the first array it makes from a Python
    list (to ask whether the list is a pandas one): half a second of every command's start, for
    nothing the command line uses. The program refuses that import in its own process;
    rtusniff imported as a library (:mod:`sniffer.library`) leaves it be."""
    if "pandas" not in sys.modules:
        sys.meta_path.insert(0, _NoPandas())


class _NoPandas(importlib.abc.MetaPathFinder):
    """Finds no pandas: ``import pandas`` raises ``ModuleNotFoundError`` (which pyarrow, asking,
    takes for pandas not installed)."""

    def find_spec(self, name: str, path: Sequence[str] | None, target: ModuleType | None = None) -> None:
        if name == "pandas":
            raise ModuleNotFoundError("the command line does without pandas", name=name)
