"""Options shared by the subcommands that read captures."""

from __future__ import annotations

import argparse
from dataclasses import replace

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.registry import all_formats


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
