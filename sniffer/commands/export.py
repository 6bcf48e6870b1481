"""``rtusniff export CAPTURE --mcap OUT.mcap --rrd OUT.rrd``: for Foxglove and for Rerun."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_jobs_option,
    add_quiet_option,
    capture_paths,
    check_outputs,
    human_size,
    open_analysis,
    source_name,
)
from sniffer.decoding_process import decoding_jobs
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.outputs import McapSink, PcapSink, RerunSink
from sniffer.io.output_files import published_whole
from sniffer.pipeline import Analysis, analyze
from sniffer.progress import progress_for
from sniffer.sinks import FileSink


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "export",
        help="export a capture as decoded MCAP (Foxglove) and/or a Rerun recording",
        description="Decode a capture and export it: --mcap for Foxglove (raw chunks, frames, transactions, "
        "parameter values per slave, a log), --rrd for the Rerun viewer (a timeline with plots and logs).",
    )
    add_capture_argument(parser)
    parser.add_argument("--mcap", metavar="OUT.mcap", help="write decoded MCAP (also a capture analyze can read)")
    parser.add_argument("--rrd", metavar="OUT.rrd", help="write a Rerun recording")
    parser.add_argument("--pcap", metavar="OUT.pcap", help="write a pcap for Wireshark: one packet per frame "
                        "(OUT.pcapng: pcapng, with each packet's direction and a comment of what rtusniff found)")
    parser.add_argument("--pcap-link", choices=["user", "udp"], default="user",
                        help="user: link type 147 (Wireshark maps it to Modbus RTU with one DLT_USER line); udp: each "
                        "frame in a UDP packet, master to slave port 502, so that Wireshark tells queries from "
                        "responses for every function (one preference: mbrtu.udp.port:502)")
    parser.add_argument("--spawn", action="store_true", help="also open the Rerun viewer (needs a display)")
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
    add_decoding_options(parser)
    add_jobs_option(parser)
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if not (args.mcap or args.rrd or args.pcap or args.spawn):
        raise RtuSniffError(ErrorKind.USAGE, "export: give --mcap OUT.mcap, --rrd OUT.rrd, --pcap OUT.pcap or --spawn")
    for option, path in (("--mcap", args.mcap), ("--rrd", args.rrd)):
        if path == "-":
            raise RtuSniffError(ErrorKind.USAGE, f"{option} -: only --pcap writes to standard output; name a file")
    if args.pcap == "-" and sys.stdout.isatty():
        raise RtuSniffError(ErrorKind.USAGE, "--pcap -: binary pcap to a terminal; pipe it (| wireshark -k -i -) "
                            "or redirect it to a file")
    check_outputs([args.mcap, args.rrd, args.pcap], capture_paths(args), force=args.force)
    if args.spawn:
        check_viewer_can_start()
    with ExitStack() as stack:
        # Each file is written beside its name and put in place once whole: an export that fails
        # half way (a damaged capture, times MCAP cannot hold) leaves nothing that passes for one;
        # Ctrl-C keeps what was exported until then, closed properly.
        parts = {option: stack.enter_context(published_whole(getattr(args, option), keep_when_interrupted=True))
                 for option, _, _ in OUTPUTS if getattr(args, option)}
        reader, analysis = open_analysis(args, stack)
        sinks = output_sinks(argparse.Namespace(**{**vars(args), **parts}), analysis, stack)
        progress = stack.enter_context(progress_for(args, reader, to_terminal=args.pcap == "-"))
        analyze(reader, source_name(args), analysis, [*(sink for _, sink in sinks), progress.sink],
                jobs=decoding_jobs(args.jobs))
    if not args.quiet:
        _tell_written(args, sinks)
    return 0


#: The outputs ``export`` offers: option → (what it is called in messages, the sink for a path).
#: Adding an output is a module with a :class:`sniffer.sinks.Sink` plus one line here; the
#: order is the order the sinks get each batch in.
OUTPUTS: list[tuple[str, str, Callable[[str, argparse.Namespace, Analysis], FileSink[Any]]]] = [
    ("mcap", "MCAP", McapSink),
    ("rrd", "Rerun recording", lambda path, args, analysis: RerunSink(path, rerun_viewer() if args.spawn else None)),
    ("pcap", "pcap", lambda path, args, analysis: PcapSink(path, udp=args.pcap_link == "udp")),
]


def output_sinks(
    args: argparse.Namespace, analysis: Analysis, stack: ExitStack
) -> list[tuple[str, FileSink[Any]]]:
    """The sinks of the outputs asked for, each closed by ``stack`` (the first whose closing
    fails to write is the error); ``--spawn`` without ``--rrd`` is a Rerun sink without a file."""
    sinks: list[tuple[str, FileSink[Any]]] = []
    for option, kind, make in OUTPUTS:
        path = getattr(args, option)
        if path or (option == "rrd" and args.spawn):
            sinks.append((kind, make(path, args, analysis)))
    # Closed last to first: the Rerun recording, then the pcap, then the MCAP, as always.
    for _, sink in sorted(sinks, key=lambda item: _CLOSE_ORDER.index(item[0])):
        stack.callback(sink.close)
    return sinks


_CLOSE_ORDER = ["MCAP", "pcap", "Rerun recording"]


def _tell_written(args: argparse.Namespace, sinks: list[tuple[str, FileSink[Any]]]) -> None:
    """One line per output on standard error: what was written where."""
    names = {kind: getattr(args, option) for option, kind, _ in OUTPUTS}
    for kind, sink in sinks:
        path = names[kind]
        if path == "-":
            print(f"wrote {sink.frames_written:,} frames as {kind} to standard output", file=sys.stderr)
        elif path:
            print(f"wrote {path}: {kind}, {sink.frames_written:,} frames, "
                  f"{human_size(os.path.getsize(path))}", file=sys.stderr)
    if args.spawn:
        frames = next(sink.frames_written for kind, sink in sinks if kind == "Rerun recording")
        print(f"sent {frames:,} frames to the Rerun viewer", file=sys.stderr)


def check_viewer_can_start() -> None:
    """``--spawn`` starts the Rerun viewer: a window. Refuse at once where none can open (the
    SDK would wait for a viewer that never starts) or where no ``rerun`` program is found."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RtuSniffError(ErrorKind.USAGE, "--spawn opens the Rerun viewer, but there is no display (DISPLAY and "
                            "WAYLAND_DISPLAY are unset); write --rrd FILE.rrd and open it with 'rerun FILE.rrd' "
                            "where there is one")
    if rerun_viewer() is None:
        raise RtuSniffError(ErrorKind.USAGE, "--spawn: the Rerun viewer ('rerun') is neither beside this Python "
                            f"({Path(sys.executable).parent}) nor on PATH; reinstall rtusniff (it brings rerun-sdk)")


def rerun_viewer() -> str | None:
    """The ``rerun`` program of this installation: beside the interpreter (a venv's bin or
    Scripts folder, not always on PATH), else on PATH."""
    name = "rerun.exe" if os.name == "nt" else "rerun"
    beside = Path(sys.executable).parent / name
    if beside.is_file():
        return str(beside)
    return shutil.which("rerun")
