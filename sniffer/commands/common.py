"""Options shared by the subcommands that read captures."""

from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack
from dataclasses import replace
from typing import TextIO

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader
from sniffer.io.registry import all_formats, open_reader
from sniffer.pipeline import Analysis, effective_line
from sniffer.profiles_io import profile_book


def add_line_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--line",
        nargs="+",
        metavar="SETTING",
        help="line settings 'BAUD FORMAT', e.g. --line 19200 8E1; overrides the capture's own",
    )
    parser.add_argument(
        "--char-timing",
        action="store_true",
        help="use 1.5/3.5 character times at every baud rate instead of the fixed "
        "750/1750 µs the Modbus specification sets above 19200 Bd",
    )


def add_timing_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--timing",
        choices=[t.value for t in TimingQuality],
        help="how far the capture's times can be trusted: exact (frame boundaries from silences, "
        "checked by content) or host (boundaries from content; times are host read times); "
        "default: what the capture says",
    )


def effective_timing(info: CaptureInfo, args: argparse.Namespace) -> TimingQuality:
    return TimingQuality(args.timing) if args.timing else info.timing


def add_response_timeout_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--response-timeout",
        type=float,
        metavar="MS",
        help="a request not answered within MS milliseconds is a timeout (default: derived from the traffic, "
        "ten times the longest recent latency, 100 ms to 1 s)",
    )


def response_timeout_ns(args: argparse.Namespace) -> int | None:
    if args.response_timeout is None:
        return None
    if not 0 < args.response_timeout <= 600_000:
        raise RtuSniffError(ErrorKind.USAGE, "--response-timeout: give milliseconds from 0 to 600000")
    timeout_ns: int = round(args.response_timeout * 1e6)
    return timeout_ns


def add_profile_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--profile",
        action="append",
        default=[],
        metavar="[SLAVE=]NAME",
        help="device profile for every slave (NAME) or for one (SLAVE=NAME), repeatable; "
        "see 'rtusniff profiles'. Without it, slaves that identify themselves (FC 43) get theirs",
    )
    parser.add_argument(
        "--profile-file",
        action="append",
        default=[],
        metavar="PATH",
        help="load a profile of your own (TOML, see docs/profiles.md); then name it with --profile",
    )


def add_decoding_options(parser: argparse.ArgumentParser) -> None:
    """Everything that says how to read and decode a capture."""
    add_line_options(parser)
    add_timing_option(parser)
    add_response_timeout_option(parser)
    add_profile_options(parser)
    add_input_format_option(parser)


def add_jobs_option(parser: argparse.ArgumentParser) -> None:
    """For commands that spend more per frame after decoding than the decoding does (not
    ``stats``: there a second process only adds the pipe)."""
    parser.add_argument(
        "--jobs",
        choices=["auto", "1", "2"],
        default="auto",
        help="processes to decode with: 2 reads, frames and pairs in a second process while this one "
        "annotates and writes (faster on two cores, same output); default auto: 2 where there are two cores",
    )


def open_analysis(args: argparse.Namespace, stack: ExitStack) -> tuple[CaptureReader, Analysis]:
    """Open ``args.capture`` and settle how to decode it."""
    book = profile_book(args.profile, args.profile_file)
    reader = open_reader(args.capture, args.input_format)
    stack.callback(close_reader, reader)
    line = apply_char_timing(effective_line(reader.info, line_override(args), args.capture), args)
    analysis = Analysis(line, effective_timing(reader.info, args), response_timeout_ns(args), profiles=book)
    return reader, analysis


def close_reader(reader: CaptureReader) -> None:
    """Close ``reader`` and tell what it found worth a warning (on standard error)."""
    reader.close()
    for warning in reader.warnings:
        print(f"warning: {warning}", file=sys.stderr)


def open_output(path: str | None, stack: ExitStack) -> TextIO:
    """Standard output, or the file ``-o`` names."""
    if path is None or path == "-":
        return sys.stdout
    try:
        return stack.enter_context(open(path, "w", encoding="utf-8"))
    except OSError as exc:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from None


def add_input_format_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--input-format",
        choices=sorted(all_formats()),
        help="capture format of the input (default: from the file suffix; text for -)",
    )


def line_override(args: argparse.Namespace) -> LineSettings | None:
    """The ``--line`` settings, or ``None`` when not given."""
    if args.line is None:
        return None
    try:
        return LineSettings.parse(" ".join(args.line), char_timing=args.char_timing)
    except ValueError as exc:
        raise RtuSniffError(ErrorKind.USAGE, f"--line: {exc}") from None


def apply_char_timing(line: LineSettings, args: argparse.Namespace) -> LineSettings:
    return replace(line, char_timing=True) if args.char_timing else line
