"""``rtusniff export CAPTURE --mcap OUT.mcap --rrd OUT.rrd``: for Foxglove and for Rerun."""

from __future__ import annotations

import argparse
import hashlib
import os
import shlex
import shutil
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, MessageBatch
from decoders.stats import Statistics
from sniffer.commands.common import add_decoding_options, add_jobs_option, check_outputs, human_size, open_analysis
from sniffer.decoding_process import decoding_jobs
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.pcap_export import PcapExporter
from sniffer.pipeline import Analysis, analyze
from sniffer.views.rows import Rows

if TYPE_CHECKING:
    from sniffer.exports.mcap_export import McapExporter
    from sniffer.exports.rerun_export import RerunExporter
    from sniffer.exports.transactions import TransactionEncoder


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "export",
        help="export a capture as decoded MCAP (Foxglove) and/or a Rerun recording",
        description="Decode a capture and export it: --mcap for Foxglove (raw chunks, frames, transactions, "
        "parameter values per slave, a log), --rrd for the Rerun viewer (a timeline with plots and logs).",
    )
    parser.add_argument("capture", help="capture file (.log/.txt text, .mcap native), or - for text on stdin")
    parser.add_argument("--mcap", metavar="OUT.mcap", help="write decoded MCAP (also a capture analyze can read)")
    parser.add_argument("--rrd", metavar="OUT.rrd", help="write a Rerun recording")
    parser.add_argument("--pcap", metavar="OUT.pcap", help="write a pcap for Wireshark: one packet per frame")
    parser.add_argument("--spawn", action="store_true", help="also open the Rerun viewer (needs a display)")
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
    add_decoding_options(parser)
    add_jobs_option(parser)
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
    check_outputs([args.mcap, args.rrd, args.pcap], [args.capture], force=args.force)
    if args.spawn:
        check_viewer_can_start()
    with ExitStack() as stack:
        reader, analysis = open_analysis(args, stack)
        view = ExportView(args, analysis)
        stack.callback(view.close)
        analyze(
            reader,
            args.capture,
            analysis,
            view,
            raw=view.raw,
            framed=view.framed if args.pcap else None,
            prepare=view.transactions if args.mcap else None,
            prepared=view.write_transactions if args.mcap else None,
            jobs=decoding_jobs(args.jobs),
        )
    _tell_written(args, view.frames)
    return 0


def _tell_written(args: argparse.Namespace, frames: int) -> None:
    """One line per output on standard error: what was written where."""
    for kind, path in (("MCAP", args.mcap), ("Rerun recording", args.rrd), ("pcap", args.pcap)):
        if path == "-":
            print(f"wrote {frames:,} frames as {kind} to standard output", file=sys.stderr)
        elif path:
            print(f"wrote {path}: {kind}, {frames:,} frames, {human_size(os.path.getsize(path))}", file=sys.stderr)
    if args.spawn:
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


class ExportView:
    """Hands messages and raw chunks to the exporters asked for."""

    def __init__(self, args: argparse.Namespace, analysis: Analysis) -> None:
        # pcap alone needs no decoding: it is fed whole batches, and annotation is skipped.
        self.wants_messages = bool(args.mcap or args.rrd or args.spawn)
        # The exports count their own bus load and errors: the statistics' tables are not written.
        self.wants_statistics = False
        self.args = args
        self.analysis = analysis
        #: Frames written (to every output: each gets every frame).
        self.frames = 0
        self.mcap: McapExporter | None = None
        self.pcap: PcapExporter | None = None
        self.rerun: RerunExporter | None = None
        if args.pcap:
            with _writing(args.pcap):
                self.pcap = PcapExporter(args.pcap)
        #: The MCAP's transactions need no decodings: built where the messages are framed and paired.
        self._transactions: TransactionEncoder | None = None
        if args.mcap:
            # Imported when asked for (the MCAP packages cost every command's start-up 13 ms).
            from sniffer.exports.mcap_export import transaction_encoder  # noqa: PLC0415

            self._transactions = transaction_encoder()

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        # Exporters that start threads (Rerun's SDK, the MCAP writer's compressor) are made here,
        # after the decoding process is forked: a fork copies no thread, only the locks they hold.
        if self.args.rrd or self.args.spawn:
            # Rerun takes a third of a second to import: only when asked for.
            from sniffer.exports.rerun_export import RerunExporter  # noqa: PLC0415

            with _writing(self.args.rrd):
                self.rerun = RerunExporter(self.args.rrd, spawn=rerun_viewer() if self.args.spawn else None)
        if self.args.mcap:
            # Imported when asked for, as Rerun is: a pcap export needs neither.
            from sniffer.exports.mcap_export import McapExporter  # noqa: PLC0415

            with _writing(self.args.mcap):
                self.mcap = McapExporter(self.args.mcap, info, line, _metadata(self.args, self.analysis))

    def raw(self, chunks: ChunkBatch) -> None:
        if self.mcap is not None:
            with _writing(self.args.mcap):
                self.mcap.raw(chunks)

    def transactions(self, batch: MessageBatch) -> tuple[Rows, npt.NDArray[np.int64]]:
        """A batch's ``/modbus/transactions`` messages and their times (in the decoding process)."""
        assert self._transactions is not None, "prepared only for an MCAP export"
        return self._transactions.rows(batch, np.arange(len(batch)))

    def write_transactions(self, transactions: tuple[Rows, npt.NDArray[np.int64]]) -> None:
        if self.mcap is not None:
            with _writing(self.args.mcap):
                self.mcap.transactions(*transactions)

    def framed(self, batch: MessageBatch) -> None:
        if not self.wants_messages:
            self.frames += len(batch)
        if self.pcap is not None:
            with _writing(self.args.pcap):
                self.pcap.batch(batch)

    def messages(self, batch: AnnotatedBatch) -> None:
        self.frames += len(batch.messages)
        if self.mcap is not None:
            with _writing(self.args.mcap):
                self.mcap.messages(batch)
        if self.rerun is not None:
            with _writing(self.args.rrd):
                self.rerun.messages(batch)

    def finish(self, statistics: Statistics) -> None:
        pass

    def close(self) -> None:
        """Closes every output; the first that fails to write is the error."""
        exporters, self.mcap, self.pcap, self.rerun = (
            [(self.args.mcap, self.mcap), (self.args.pcap, self.pcap), (self.args.rrd, self.rerun)], None, None, None)
        with ExitStack() as closing:
            for path, exporter in exporters:
                if exporter is not None:
                    closing.callback(_close, path, exporter)


def _close(path: str | None, exporter: McapExporter | PcapExporter | RerunExporter) -> None:
    with _writing(path):
        exporter.close()


@contextmanager
def _writing(path: str | None) -> Iterator[None]:
    """An exporter's write failures (a missing folder, a full disk) as one error naming its file."""
    try:
        yield
    except (OSError, RuntimeError) as exc:  # RuntimeError: how Rerun's SDK reports I/O errors
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {reason}", path=path or "the viewer") from None


def _metadata(args: argparse.Namespace, analysis: Analysis) -> dict[str, str]:
    book = analysis.profiles
    profiles = "generic" if book is None else ", ".join(
        [f"default {book.default.id}", *(f"slave {s}: {p.id}" for s, p in sorted(book.per_slave.items()))]
    )
    return {
        "source": args.capture,
        "source_sha256": _sha256(args.capture),
        "command": shlex.join(args.command_line),
        "profiles": profiles,
    }


def _sha256(path: str) -> str:
    if path == "-":
        return "(standard input)"
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
