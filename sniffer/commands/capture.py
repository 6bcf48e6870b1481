"""``rtusniff capture PORT``: record, decode and view a live RS485 line, passively."""

from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING

from decoders.capture import GUESSED_LINE
from decoders.line import LineSettings
from sniffer.commands.common import (
    add_pcap_link_option,
    add_profile_options,
    add_response_timeout_option,
    check_outputs,
    response_timeout_ns,
    typed_registers,
)
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.outputs import PcapSink
from sniffer.exports.streams import add_stream_options, check_streams, stream_sinks
from sniffer.io.registry import find_format
from sniffer.io.rotation import rotated_files
from sniffer.line_probe import PROBE_SECONDS, probe_line
from sniffer.profiles_io import profile_book
from sniffer.recorder import Rotation

if TYPE_CHECKING:
    from rich.console import Console


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "capture",
        help="record and decode a live serial port (a passive tap: never writes to it)",
        description="Read a serial port passively (RTS and DTR off, nothing written), record every byte with "
        "its time, and show the decoded traffic as it happens.",
    )
    parser.add_argument("port", help="serial port, e.g. /dev/ttyUSB0 (see 'rtusniff ports')")
    parser.add_argument("--line", required=True, metavar="'BAUD FORMAT'|auto",
                        help="'BAUD FORMAT' (e.g. --line 19200 8E1), or 'auto' to find them by listening")
    parser.add_argument("--probe-seconds", type=float, default=PROBE_SECONDS,
                        help=f"with --line auto: how long to listen per setting (default {PROBE_SECONDS:g})")
    parser.add_argument("--char-timing", action="store_true", help="as for analyze")
    parser.add_argument("-o", "--output", help="record to FILE.mcap (native) or FILE.log (text), flushed every second")
    parser.add_argument("--rotate", help="start a new file after a size (100MB) or a duration (1h): FILE-0001.mcap, …")
    parser.add_argument("--quiet", action="store_true", help="only record: no decoding, no view")
    parser.add_argument("--format", choices=["view", "jsonl", "none"], default=None,
                        help="view: live terminal view (default); jsonl: stream JSON Lines records to stdout; none: "
                        "no view, decoding for the other outputs alone (the default with --pcap -)")
    parser.add_argument("--pcap", metavar="OUT.pcapng", help="also write the frames as Wireshark reads them, as they "
                        "are framed: a file (.pcapng: with each packet's direction and a comment of what rtusniff "
                        "found), a FIFO, or - for standard output (| wireshark -C rtusniff -k -i -)")
    add_pcap_link_option(parser)
    parser.add_argument("--duration", type=float, metavar="SECONDS", help="stop after SECONDS")
    add_response_timeout_option(parser)
    add_profile_options(parser)
    add_stream_options(parser, replay=False)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

    from sniffer.live_capture import CaptureOptions, run_capture  # noqa: PLC0415 - its live view is rich's

    # A message naming a file stays one line and says the name as it is (no rich markup: "[site-a]").
    err = Console(stderr=True, highlight=False, markup=False, soft_wrap=True)
    if args.output is None and args.quiet:
        raise RtuSniffError(ErrorKind.USAGE, "--quiet records only: give a file with -o")
    if args.output is not None:
        check_recording(args.output, rotating=bool(args.rotate))
    if args.quiet and (args.foxglove is not None or args.rerun is not None or args.pcap is not None):
        raise RtuSniffError(ErrorKind.USAGE, "--quiet records only: --foxglove, --rerun and --pcap need the decoding")
    mode = _mode(args)
    check_streams(args)
    if args.pcap not in (None, "-"):
        check_outputs([args.pcap, args.output], [args.port], force=False)
    book = profile_book(args.profile, args.profile_file, typed_registers(args))
    line, guessed = line_settings(args.line, args.port, args.char_timing, args.probe_seconds, err)
    options = CaptureOptions(
        port=args.port,
        line=line,
        output=args.output,
        rotation=Rotation.parse(args.rotate) if args.rotate else None,
        mode=mode,
        duration_s=args.duration,
        response_timeout_ns=response_timeout_ns(args),
        profiles=book,
        streams=tuple(stream_sinks(args, replay=False)),
        pcap=None if args.pcap is None else PcapSink(args.pcap, udp=args.pcap_link == "udp"),
        line_guessed=guessed,
    )
    return run_capture(options, sys.stdout, err)


def _mode(args: argparse.Namespace) -> str:
    if args.quiet:
        return "quiet"
    if args.pcap == "-":
        if args.format not in (None, "none"):
            raise RtuSniffError(ErrorKind.USAGE, f"--pcap - writes the pcap to standard output: --format {args.format} "
                                "cannot share it")
        if sys.stdout.isatty():
            raise RtuSniffError(ErrorKind.USAGE, "--pcap -: binary pcap to a terminal; pipe it "
                                "(| wireshark -C rtusniff -k -i -) or name a file")
        return "none"
    return str(args.format or "view")


def check_recording(path: str, *, rotating: bool) -> None:
    """A recording is a new file (or rotation) of a format rtusniff writes."""
    find_format(path, option="", purpose="write")
    if os.path.lexists(path) and not rotating:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists; capture never overwrites a recording", path=path)
    taken = rotated_files(path) if rotating else []
    if taken:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"exists ({len(taken)} file(s) of an earlier rotation); "
                            "capture never overwrites a recording: choose another name", path=taken[0])


def line_settings(text: str, port: str, char_timing: bool, probe_seconds: float,
                  err: Console) -> tuple[LineSettings, str | None]:
    """``--line``: 'BAUD FORMAT', or ``auto``: found by listening to ``port`` (the report to ``err``,
    and as the recording's note that says them guessed, the second value)."""
    if text.strip().lower() == "auto":
        line, report = probe_line(port, probe_seconds)
        err.print(report)
        return (LineSettings(line.baud, line.data_bits, line.parity, line.stop_bits, char_timing),
                f"{GUESSED_LINE}--line auto: {report}")
    try:
        return LineSettings.parse(text, char_timing=char_timing), None
    except ValueError as exc:
        raise RtuSniffError(ErrorKind.USAGE, f"--line: {exc}, or 'auto'") from None
