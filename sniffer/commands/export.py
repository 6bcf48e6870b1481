"""``rtusniff export CAPTURE --mcap OUT.mcap --rrd OUT.rrd``: for Foxglove and for Rerun."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from contextlib import ExitStack
from typing import Any

from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_follow_option,
    add_jobs_option,
    add_pcap_link_option,
    add_quiet_option,
    capture_paths,
    check_outputs,
    human_size,
    replay_speed,
)
from sniffer.decoding_process import decoding_jobs
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.outputs import McapSink, ParquetSink, PcapSink, RerunSink
from sniffer.exports.streams import RerunStreamSink, add_stream_options, check_streams, stream_sinks
from sniffer.io.output_files import published_whole
from sniffer.library import Capture
from sniffer.many_captures import Tally, add_each_options, capture_files, each_result, jobs_for_each
from sniffer.pipeline import Analysis
from sniffer.progress import progress_for, shown
from sniffer.sinks import FileSink
from sniffer.wording import counted


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
    add_pcap_link_option(parser)
    parser.add_argument("--parquet", metavar="DIR", help="add the decoded tables (frames, transactions, values, "
                        "anomalies, latencies) to a Parquet dataset in DIR, partitioned by bus and date, for "
                        "DuckDB, Polars, Spark, Trino; more captures add files, never rewrite one")
    parser.add_argument("--bus", metavar="NAME", help="with --parquet: the bus partition's name (default: the "
                        "capture file's name without its suffix)")
    parser.add_argument("--spawn", action="store_true", help="the same as --rerun spawn")
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
    add_decoding_options(parser)
    add_follow_option(parser)
    add_stream_options(parser, replay=True)
    add_jobs_option(parser)
    add_each_options(parser, "each capture added to the --parquet dataset as its own")
    add_quiet_option(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.each:
        return _run_each(args)
    if args.spawn:
        if args.rerun not in (None, "spawn"):
            raise RtuSniffError(ErrorKind.USAGE, "--spawn is --rerun spawn: give one --rerun")
        args.rerun = "spawn"
    if not (args.mcap or args.rrd or args.pcap or args.parquet or args.foxglove or args.rerun):
        raise RtuSniffError(ErrorKind.USAGE, "export: give --mcap OUT.mcap, --rrd OUT.rrd, --pcap OUT.pcap, "
                            "--parquet DIR, --foxglove [HOST:]PORT or --rerun spawn|ADDRESS")
    check_dataset(args)
    for option, path in (("--mcap", args.mcap), ("--rrd", args.rrd)):
        if path == "-":
            raise RtuSniffError(ErrorKind.USAGE, f"{option} -: only --pcap writes to standard output; name a file")
    if args.pcap == "-" and sys.stdout.isatty():
        raise RtuSniffError(ErrorKind.USAGE, "--pcap -: binary pcap to a terminal; pipe it (| wireshark -k -i -) "
                            "or redirect it to a file")
    check_outputs([args.mcap, args.rrd, args.pcap], capture_paths(args), force=args.force, following=args.follow)
    check_streams(args)
    jobs = decoding_jobs(args.jobs, follow=args.follow, paced=replay_speed(args) is not None)
    # Each file is written beside its name and put in place once whole: an export that fails
    # half way (a damaged capture, times MCAP cannot hold) leaves nothing that passes for one;
    # Ctrl-C keeps what was exported until then, closed properly, under a name that says it is
    # incomplete (the MCAP in a metadata record too), and says where.
    kept: dict[str, list[str]] = {option: [] for option, _, _ in OUTPUTS}
    sinks: list[tuple[str, FileSink[Any]]] = []
    try:
        with ExitStack() as stack:
            parts = {option: stack.enter_context(published_whole(getattr(args, option),
                                                                 kept_when_interrupted=kept[option]))
                     for option, _, _ in OUTPUTS if getattr(args, option) and option != "parquet"}
            capture = Capture(args, stack)
            sinks = output_sinks(argparse.Namespace(**{**vars(args), **parts}), capture.analysis, stack)
            progress = stack.enter_context(progress_for(args, capture.reader, streaming=args.pcap == "-"))
            try:
                capture.decode([progress.sink, *(sink for _, sink in sinks)], jobs=jobs)
            except KeyboardInterrupt:
                for _, sink in sinks:
                    sink.interrupted()
                raise
    except KeyboardInterrupt:
        _tell_kept(args, sinks, kept)
        raise
    if not args.quiet:
        _tell_written(args, sinks)
    return 0


def _tell_kept(args: argparse.Namespace, sinks: list[tuple[str, FileSink[Any]]], kept: dict[str, list[str]]) -> None:
    """After Ctrl-C: where each output was kept, incomplete, and how many frames it holds."""
    for option, kind, _ in OUTPUTS:
        frames = next((sink.frames_written for named, sink in sinks if named == kind), 0)
        for name in kept[option]:
            print(f"interrupted: {getattr(args, option)} kept incomplete as {name} ({frames:,} frames)",
                  file=sys.stderr)


#: The outputs ``export`` offers: option → (what it is called in messages, the sink for a path).
#: Adding an output is a module with a :class:`sniffer.sinks.Sink` plus one line here; the
#: order is the order the sinks get each batch in.
OUTPUTS: list[tuple[str, str, Callable[[str, argparse.Namespace, Analysis], FileSink[Any]]]] = [
    ("mcap", "MCAP", McapSink),
    ("rrd", "Rerun recording", lambda path, args, analysis: RerunSink(path)),
    ("pcap", "pcap", lambda path, args, analysis: PcapSink(path, udp=args.pcap_link == "udp")),
    # A folder that grows: its files are published whole by the sink itself.
    ("parquet", "Parquet dataset", ParquetSink),
]


def output_sinks(
    args: argparse.Namespace, analysis: Analysis, stack: ExitStack
) -> list[tuple[str, FileSink[Any]]]:
    """The sinks of the outputs asked for, each closed by ``stack`` (the first whose closing
    fails to write is the error); ``--rerun`` with ``--rrd`` is one Rerun sink, the file and
    the viewer fed from one recording."""
    sinks: list[tuple[str, FileSink[Any]]] = []
    for option, kind, make in OUTPUTS:
        path = getattr(args, option)
        if path and not (option == "rrd" and args.rerun):
            sinks.append((kind, make(path, args, analysis)))
    for sink in stream_sinks(args, replay=True, rrd=args.rrd):
        sinks.append(("Rerun recording" if isinstance(sink, RerunStreamSink) else "Foxglove stream", sink))
    # Closed last to first: the Rerun recording, then the pcap, then the MCAP, as always.
    for _, sink in sorted(sinks, key=lambda item: _CLOSE_ORDER.index(item[0])):
        stack.callback(sink.close)
    return sinks


_CLOSE_ORDER = ["MCAP", "pcap", "Parquet dataset", "Foxglove stream", "Rerun recording"]


def _tell_written(args: argparse.Namespace, sinks: list[tuple[str, FileSink[Any]]]) -> None:
    """One line per output on standard error: what was written where."""
    names = {kind: getattr(args, option) for option, kind, _ in OUTPUTS}
    for kind, sink in sinks:
        path = names.get(kind)
        if path == "-":
            print(f"wrote {counted(sink.frames_written, 'frame')} as {kind} to standard output", file=sys.stderr)
        elif isinstance(sink, ParquetSink):
            size = sum(os.path.getsize(file) for file in sink.files)
            print(f"added {len(sink.files)} files to {path}: {kind}, {counted(sink.frames_written, 'frame')}, "
                  f"{human_size(size)}", file=sys.stderr)
        elif path:
            print(f"wrote {path}: {kind}, {counted(sink.frames_written, 'frame')}, "
                  f"{human_size(os.path.getsize(path))}", file=sys.stderr)
    for kind, sink in sinks:
        if kind == "Foxglove stream":
            print(f"served {counted(sink.frames_written, 'frame')} to Foxglove", file=sys.stderr)
    if args.rerun:
        frames = next(sink.frames_written for kind, sink in sinks if kind == "Rerun recording")
        print(f"sent {counted(frames, 'frame')} to the Rerun viewer", file=sys.stderr)


def check_dataset(args: argparse.Namespace) -> None:
    """``--parquet DIR``: a folder (made if missing), never a file nor standard output."""
    if args.bus is not None and not args.parquet:
        raise RtuSniffError(ErrorKind.USAGE, "--bus names the partition of a --parquet dataset: give --parquet DIR")
    if not args.parquet:
        return
    if args.parquet == "-" or (os.path.exists(args.parquet) and not os.path.isdir(args.parquet)):
        raise RtuSniffError(ErrorKind.USAGE, "--parquet takes a folder (a dataset of many files)", path=args.parquet)
    from sniffer.exports.parquet_export import bus_name_fault  # noqa: PLC0415 - pyarrow, only for --parquet

    if args.bus is not None and (fault := bus_name_fault(args.bus)) is not None:
        raise RtuSniffError(ErrorKind.USAGE, f"--bus {args.bus!r}: {fault}")


def _run_each(args: argparse.Namespace) -> int:
    """``--each --parquet DIR``: every capture exported as its own into one dataset, in a pool."""
    others = [option for option in ("mcap", "rrd", "pcap", "foxglove", "rerun", "follow", "spawn")
              if getattr(args, option)]
    if not args.parquet or others:
        raise RtuSniffError(ErrorKind.USAGE, "--each exports many captures into one --parquet dataset (files of one "
                            "capture, streams and --follow take one capture)")
    check_dataset(args)
    files = capture_files(args.capture)
    one = argparse.Namespace(**{**vars(args), "each": False, "quiet": True, "jobs": "1"})
    tally, frames, added = Tally(len(files)), 0, []
    for exported, files_added in each_result(files, _export_one, one, jobs_for_each(args.jobs), tally,
                                             show=shown(args, streaming=False)):
        frames += exported
        added += files_added
    if not args.quiet and added:
        size = sum(os.path.getsize(path) for path in added)
        print(f"added {len(added)} files to {args.parquet}: Parquet dataset, {frames:,} frames of {tally.done} "
              f"captures, {human_size(size)}", file=sys.stderr)
    return tally.exit_code()


def _export_one(args: argparse.Namespace) -> tuple[int, list[str]]:
    """One capture of ``--each`` into the dataset (in a process of the pool): frames, files added."""
    with ExitStack() as stack:
        capture = Capture(args, stack)
        sink = ParquetSink(args.parquet, args, capture.analysis)
        stack.callback(sink.close)
        capture.decode([sink])
    return sink.frames_written, sink.files
