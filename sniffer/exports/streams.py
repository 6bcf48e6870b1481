"""Live streams to viewers as sinks (:mod:`sniffer.sinks`): ``--foxglove`` and ``--rerun``.

``capture`` streams what it decodes as it happens; ``analyze`` and ``export`` replay a
file at its own speed (``--speed``, :mod:`sniffer.io.pacing`) or follow a growing
recording (``--follow``). Both streams carry what the files carry: the Foxglove stream the
MCAP export's channels and schemas (:class:`~sniffer.exports.mcap_export.DecodedChannels`),
the Rerun stream the ``.rrd`` export's entities on the ``capture_time`` timeline.

Neither may hold up a capture: both SDKs queue and send from threads of their own, a viewer
that goes away is forgotten (a warning, never an exit), and the recording, written by its
own thread from the reader's hand-over, never waits for either.
"""

from __future__ import annotations

import argparse
import os
import re
import secrets
import shutil
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.stats import SkippedReads
from sniffer.encoding.rows import Rows
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.foxglove_gate import Door
from sniffer.sinks import FileSink

if TYPE_CHECKING:
    from sniffer.exports.foxglove_server import FoxgloveServerWriter
    from sniffer.exports.mcap_export import DecodedChannels  # noqa: F401 - named in a string
    from sniffer.exports.rerun_export import RerunExporter  # noqa: F401 - named in a string

#: foxglove.Log's WARNING.
_WARNING = 3
#: Where ``--rerun spawn`` starts the viewer (Rerun's own default port).
SPAWN_PORT = 9876
#: The Foxglove app's default connection.
DEFAULT_PORT = 8765
#: ``--foxglove-token`` alone: make one.
NEW_TOKEN = "\0new"


def parse_address(text: str) -> tuple[str, int]:
    """``--foxglove [HOST:]PORT`` → host and port; the host defaults to this machine only."""
    host, _, port_text = text.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise RtuSniffError(ErrorKind.USAGE, f"--foxglove {text}: give a port (8765) or HOST:PORT (0.0.0.0:8765 "
                            "to let other machines connect; port 0: any free port)")
    return host, port


def add_stream_options(parser: argparse.ArgumentParser, *, replay: bool) -> None:
    """``--foxglove`` and ``--rerun``; ``replay``: also ``--speed`` (a file, not a port)."""
    group = parser.add_argument_group("live viewers")
    group.add_argument("--foxglove", nargs="?", const=str(DEFAULT_PORT), metavar="[HOST:]PORT",
                       help=f"serve the decoded traffic to the Foxglove app over its WebSocket protocol (default port "
                       f"{DEFAULT_PORT}, this machine only; 0.0.0.0:PORT lets other machines connect): the MCAP "
                       "export's channels, so one layout serves both")
    group.add_argument("--foxglove-token", nargs="?", const=NEW_TOKEN, metavar="SECRET",
                       help="with --foxglove, let in only clients whose URL carries ?token=SECRET (alone: a new random "
                       "one, printed in the URL to open); for a port other machines reach")
    group.add_argument("--foxglove-allow-origin", action="append", metavar="ORIGIN",
                       help="with --foxglove, also let in WebSockets from this web origin (a self-hosted Foxglove, "
                       "e.g. https://foxglove.example.com); web pages of other origins are refused")
    group.add_argument("--rerun", metavar="spawn|ADDRESS",
                       help="stream to a Rerun viewer: 'spawn' starts one (needs a display); ADDRESS is a running "
                       "viewer's (PORT, HOST:PORT or rerun+http://HOST:PORT/proxy; start one with 'rerun')")
    if replay:
        group.add_argument("--speed", default=None, metavar="FACTOR|max",
                           help="with --foxglove or --rerun, replay at FACTOR times the recorded speed (default 1; "
                           "'max': as fast as it decodes)")


def rerun_address(text: str) -> str:
    """``--rerun ADDRESS`` as the gRPC URL Rerun's SDK takes."""
    if text.startswith(("rerun://", "rerun+http://", "rerun+https://")):
        return text
    host, _, port_text = text.rpartition(":")
    if port_text.isdigit() and 0 < int(port_text) < 65536 and (host or ":" not in text):
        return f"rerun+http://{host or '127.0.0.1'}:{port_text}/proxy"
    raise RtuSniffError(ErrorKind.USAGE, f"--rerun {text}: give 'spawn', a port (9876), HOST:PORT or "
                        "rerun+http://HOST:PORT/proxy")


class StreamSink(Protocol):
    def live_status(self) -> str:
        """One line for the live view: where the stream goes, what it skipped."""
        ...


class FoxgloveSink(FileSink["DecodedChannels"]):
    """The decoded channels served live (:mod:`sniffer.exports.foxglove_server`)."""

    wants_messages = True

    def __init__(self, address: str, tell: Callable[[str], None], *, wait_for_viewer: bool = False,
                 door: Door | None = None) -> None:
        super().__init__(None)
        self._host, self._port = parse_address(address)
        self._door = door or Door(tell=tell)
        self._tell, self._wait = tell, wait_for_viewer
        self.server: FoxgloveServerWriter | None = None
        from sniffer.exports.mcap_export import transaction_encoder  # noqa: PLC0415 - only for a stream

        encoder = transaction_encoder()

        def transactions(batch: MessageBatch) -> tuple[Rows, npt.NDArray[np.int64]] | None:
            # In a decoding process (forked before the server started) there is no server to ask.
            if self.server is not None and not self.server.watched():
                return None
            return encoder.rows(batch, np.arange(len(batch)))

        self.prepare = transactions

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        from sniffer.exports.foxglove_server import FoxgloveServerWriter  # noqa: PLC0415 - a native library
        from sniffer.exports.mcap_export import DecodedChannels  # noqa: PLC0415

        self.server = FoxgloveServerWriter(self._host, self._port, f"rtusniff: {source}", self._door)
        self.exporter = DecodedChannels(self.server, info, target="the Foxglove stream")
        self._tell(f"Foxglove: open {self.server.url} (Open connection → Foxglove WebSocket)")
        if self._host in ("127.0.0.1", "localhost", "::1"):
            port = self.server.port
            self._tell(f"  this machine only; from another: --foxglove 0.0.0.0:{port} --foxglove-token, "
                       f"or ssh -L {port}:localhost:{port}")
        elif self._door.token is None:
            self._tell(f"  any machine that reaches port {self.server.port} can watch; --foxglove-token lets in only "
                       "those given the URL")
        if self._wait:
            self._tell("waiting for a Foxglove client to subscribe before replaying; Ctrl-C to stop")
            while not self.server.subscriptions.first.wait(0.2):
                pass

    def live_status(self) -> str:
        if self.server is None:
            return "Foxglove: not started"
        return f"Foxglove {self.server.url}" + ("" if self.server.watched() else " (no client)")

    def _watched(self) -> bool:
        """Messages are built only while a client subscribes: a capture served to nobody pays nothing."""
        return self.server is not None and self.server.watched()

    def messages(self, batch: AnnotatedBatch) -> None:
        self.frames_written += len(batch.messages)
        if self.exporter is not None and self._watched():
            with self.writing():
                self.exporter.messages(batch)

    def prepared(self, value: tuple[Rows, npt.NDArray[np.int64]] | None) -> None:
        if self.exporter is not None and value is not None:
            with self.writing():
                self.exporter.transactions(*value)

    def gap(self, skipped: SkippedReads) -> None:
        text = (f"rtusniff skipped {skipped.reads:,} reads ({skipped.size:,} bytes) here: decoding fell behind; "
                "the recording has them")
        if self.exporter is not None and self.server is not None:
            self.exporter.log_line(skipped.t_ns, _WARNING, text)
            self.server.status(text)


class RerunStreamSink(FileSink["RerunExporter"]):
    """The ``.rrd`` export's entities, streamed to a viewer (and written to ``path`` if given).

    A viewer that goes away (closed, killed, its machine gone) is a warning, and the stream
    stops: what is being decoded goes on (a capture records every byte whatever the viewer
    does). Where a ``.rrd`` file is written too, a failure is an error (the file is an output)."""

    wants_messages = True

    def __init__(self, path: str | None, viewer: str, tell: Callable[[str], None]) -> None:
        super().__init__(path)
        self._viewer, self._tell = viewer, tell
        self._url = viewer
        #: Frames decoded after the viewer went away (``None``: it has not).
        self.frames_unsent: int | None = None

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        from sniffer.exports.rerun_export import RerunExporter, spawn_viewer  # noqa: PLC0415 - a third of a second

        with self.writing():
            if self._viewer == "spawn":
                url = spawn_viewer(SPAWN_PORT, rerun_viewer())
                self._tell(f"Rerun: started the viewer ({url})")
            else:
                url = rerun_address(self._viewer)
                self._tell(f"Rerun: streaming to {url}")
            self._url = url
            self.exporter = RerunExporter(self.path, url, live=True)

    def messages(self, batch: AnnotatedBatch) -> None:
        self.frames_written += len(batch.messages)
        if self.frames_unsent is not None:
            self.frames_unsent += len(batch.messages)
        elif self.exporter is not None:
            with self._viewer_may_leave():
                self.exporter.messages(batch)

    @contextmanager
    def _viewer_may_leave(self) -> Iterator[None]:
        if self.path is not None:
            with self.writing():
                yield
            return
        try:
            yield
        except (OSError, RuntimeError) as exc:  # RuntimeError: how Rerun's SDK says a connection broke
            exporter, self.exporter, self.frames_unsent = self.exporter, None, 0
            reason = (str(exc).splitlines() or [type(exc).__name__])[0]
            self._tell(f"warning: Rerun: the viewer at {self._url} went away ({reason}); decoding goes on without it")
            if exporter is not None:
                exporter.abandon()

    def live_status(self) -> str:
        if self.frames_unsent is not None:
            return f"Rerun {self._url} went away ({self.frames_unsent:,} frames not sent)"
        skipped = self.exporter.skipped_rows if self.exporter is not None else 0
        return f"Rerun {self._url}" + (f", skipped {skipped:,} values (Rerun fell behind)" if skipped else "")

    def close(self) -> None:
        exporter = self.exporter
        if self.path is not None:
            super().close()
        elif exporter is not None:
            with self._viewer_may_leave():
                exporter.close()
            self.exporter = None
        if self.frames_unsent:
            self._tell(f"warning: Rerun: {self.frames_unsent:,} frames decoded after the viewer went away were not "
                       "sent to it (the recording has them)")
        if exporter is not None and exporter.skipped_rows:
            self._tell(f"warning: Rerun: skipped {exporter.skipped_rows:,} values the viewer stream could not keep "
                       "up with (the recording and the files have them)")


def stream_sinks(args: argparse.Namespace, *, replay: bool, rrd: str | None = None) -> list[FileSink[Any]]:
    """The live viewer sinks ``args`` ask for; ``rrd``: the Rerun stream also writes this file.
    A replay waits for a Foxglove client before it starts (unless ``--speed max``), so that
    the viewer sees it from the first frame."""
    check_streams(args)
    sinks: list[FileSink[Any]] = []
    if args.foxglove is not None:
        wait = replay and not getattr(args, "follow", False) and getattr(args, "speed", None) != "max"
        door = Door(tuple(args.foxglove_allow_origin or ()), _token(args.foxglove_token), _tell_stderr)
        sinks.append(FoxgloveSink(args.foxglove, _tell_stderr, wait_for_viewer=wait, door=door))
    if args.rerun is not None:
        sinks.append(RerunStreamSink(rrd, args.rerun, _tell_stderr))
    return sinks


def _token(given: str | None) -> str | None:
    """``--foxglove-token``: none, a new random one (the option alone), or the one given."""
    if given is None:
        return None
    return secrets.token_urlsafe(16) if given == NEW_TOKEN else given


def check_streams(args: argparse.Namespace) -> None:
    """Wrong addresses and a viewer that cannot start are usage errors before anything runs."""
    if args.foxglove is not None:
        parse_address(args.foxglove)
    elif args.foxglove_token is not None or args.foxglove_allow_origin:
        raise RtuSniffError(ErrorKind.USAGE, "--foxglove-token and --foxglove-allow-origin go with --foxglove")
    for origin in args.foxglove_allow_origin or ():
        if not re.fullmatch(r"[a-z][a-z0-9+.-]*://[^\s/]+", origin, re.IGNORECASE):
            raise RtuSniffError(ErrorKind.USAGE, f"--foxglove-allow-origin {origin}: give an origin as a browser "
                                "sends it, e.g. https://foxglove.example.com")
    if args.foxglove_token not in (None, NEW_TOKEN) and not re.fullmatch(r"[A-Za-z0-9_.~-]{16,}", args.foxglove_token):
        raise RtuSniffError(ErrorKind.USAGE, "--foxglove-token: at least 16 letters, digits or _.~- (or the option "
                            "alone for a new random one)")
    if args.rerun == "spawn":
        check_viewer_can_start("--rerun spawn")
    elif args.rerun is not None:
        rerun_address(args.rerun)


def check_viewer_can_start(option: str) -> None:
    """Starting the Rerun viewer opens a window. Refuse at once where none can open (the SDK
    would wait for a viewer that never starts) or where no ``rerun`` program is found."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RtuSniffError(ErrorKind.USAGE, f"{option} opens the Rerun viewer, but there is no display (DISPLAY and "
                            "WAYLAND_DISPLAY are unset); start 'rerun' where there is one and give --rerun HOST:PORT, "
                            "or write --rrd FILE.rrd and open it with 'rerun FILE.rrd'")
    if rerun_viewer() is None:
        raise RtuSniffError(ErrorKind.USAGE, f"{option}: the Rerun viewer ('rerun') is neither beside this Python "
                            f"({Path(sys.executable).parent}) nor on PATH; reinstall rtusniff (it brings rerun-sdk)")


def rerun_viewer() -> str | None:
    """The ``rerun`` program of this installation: beside the interpreter (a venv's bin or
    Scripts folder, not always on PATH), else on PATH."""
    name = "rerun.exe" if os.name == "nt" else "rerun"
    beside = Path(sys.executable).parent / name
    if beside.is_file():
        return str(beside)
    return shutil.which("rerun")


def _tell_stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)
