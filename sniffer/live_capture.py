"""A live capture: reader thread → recorder (every byte) and → decoder and view (when they keep up).

The reader thread only reads, stamps and hands over: to the recorder, which never
makes it wait, and to a bounded queue for decoding and display. When the view
falls behind, the queue drops reads for the view only and says how many; the
recording has every byte.
"""

from __future__ import annotations

import queue
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TextIO, cast

from rich.console import Console
from rich.live import Live

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.framer import LIVE_IDLE_NS
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from decoders.profiles.book import ProfileBook
from decoders.stats import SkippedReads
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.outputs import PcapSink
from sniffer.exports.streams import StreamSink
from sniffer.pipeline import Delivery
from sniffer.recorder import Recorder, Rotation
from sniffer.serial_source import ICOUNT_FIELDS, PortGoneError, PortStatus, SerialSource
from sniffer.sinks import Sink
from sniffer.stopping import (
    INTERRUPTED,
    TERMINATED,
    StopRequest,
    TerminatedError,
    handle_stop_signals,
    restore_signals,
    whole_writes,
)
from sniffer.tool_version import tool_version
from sniffer.views.jsonl import JsonlView
from sniffer.views.live import LiveState, LiveView

VIEW_QUEUE_READS = 1024
REFRESH_S = 0.25
#: With a live viewer: how often decoding takes the new reads (a frame's latency to the viewer;
#: each round costs the decoding and every sink a fixed part, so not more often).
STREAM_WAIT_S = 0.025
READ_TIMEOUT_S = 0.1
COUNTERS_EVERY_S = 1.0
#: The least quiet that ends a frame live (a prompt port's reads still jitter by milliseconds).
MIN_LIVE_GAP_NS = 20_000_000


def live_gap_ns(line: LineSettings, status: PortStatus) -> int:
    """The quiet between reads that certainly ends a frame on this port, so that a frame is
    decoded (and shown, and streamed) once the line is that quiet after it: above t3.5 and twice
    the port's delivery delay (an FTDI latency timer), at least ``MIN_LIVE_GAP_NS``; where the
    delay is unknown (another USB adapter), the framer's 100 ms."""
    delivery_ms = status.delivery_ms
    if delivery_ms is None:
        return LIVE_IDLE_NS
    return max(MIN_LIVE_GAP_NS, int(line.t3_5_ns) + 10_000_000, 2 * delivery_ms * 1_000_000 + 10_000_000)


@dataclass(frozen=True)
class CaptureOptions:
    port: str
    line: LineSettings
    output: str | None
    rotation: Rotation | None
    mode: str  # "view", "jsonl", "none" (decoded for the outputs alone) or "quiet" (recorded only)
    duration_s: float | None
    response_timeout_ns: int | None
    profiles: ProfileBook | None
    #: Live viewers fed beside the view (``--foxglove``, ``--rerun``): decoded as soon as read.
    streams: tuple[Sink, ...] = ()
    #: ``--pcap``: the frames as Wireshark reads them, written as they are framed (a file, a FIFO
    #: such as Wireshark's extcap pipe, or standard output).
    pcap: PcapSink | None = None
    #: The recording's note saying the line settings were found by listening (``--line auto``).
    line_guessed: str | None = None


@dataclass
class _Skipped:
    """Reads the reader thread dropped (the decoding queue was full) before the next one queued."""

    reads: int = 0
    size: int = 0
    #: When the read after them was taken.
    t_ns: int = 0


@dataclass
class _Shared:
    """What the reader thread tells the main thread."""

    stop: threading.Event
    #: Reads for decoding, in order; a ``_Skipped`` marks where reads were dropped before the next.
    reads: queue.Queue[Chunk | _Skipped]
    behind_reads: int = 0
    gone: str | None = None
    failure: BaseException | None = None


def run_capture(options: CaptureOptions, out: TextIO, err: Console) -> int:
    """Capture until Ctrl-C, SIGTERM, the end of ``duration_s`` or the loss of the port.
    ``err``: where messages go, a console that neither highlights, reads markup in, nor wraps
    them (a message naming a file says the name as it is, on one line)."""
    source = SerialSource(options.port, options.line)
    status = source.open()
    recorder = _recorder(options, status)
    shared = _Shared(threading.Event(), queue.Queue(VIEW_QUEUE_READS))
    reader = threading.Thread(target=_read, args=(source, recorder, shared, options.mode != "quiet"),
                              name="rtusniff-reader", daemon=True)
    # Handlers for both signals, whatever this process inherited: a shell starts a background job
    # with SIGINT ignored, and `kill -INT` must still stop a capture cleanly (as dumpcap's does).
    request = StopRequest(shared.stop)
    previous = handle_stop_signals(request)
    code = 0
    session = _Session(options, status, recorder, shared, out, request=request)
    try:
        if recorder is not None:
            recorder.start()
        reader.start()
        target = f" to {options.output}" if options.output else ""
        err.print(f"capturing {options.port} at {options.line.format()}{target}; Ctrl-C to stop")
        if status.modem_lines is not None and any(status.modem_lines.values()):
            err.print(f"warning: {options.port}: {status.modem_note()}")
        session.run(source)
        if request.asked is not None:  # a signal that came while a record was written: stopped after it
            code = INTERRUPTED if request.asked == signal.SIGINT else TERMINATED
    except KeyboardInterrupt:
        code = INTERRUPTED
    except TerminatedError:
        code = TERMINATED
    finally:
        restore_signals(previous)
        shared.stop.set()
        reader.join(timeout=2)
        source.close()
        if recorder is not None:
            if session.heard_until_ns is not None:
                # Until when the line was heard: the recording says it as a chunk without bytes,
                # so that decoding it gives the last requests the verdicts the live view gave.
                recorder.add(Chunk(session.heard_until_ns, b""))
            recorder.stop()
        session.finish()
    warning = session.decoder.line_check.warning()
    if warning is not None:
        err.print(f"warning: {options.port}: {warning}")
    return _report(code, options, recorder, shared, err)


def _recorder(options: CaptureOptions, status: PortStatus) -> Recorder | None:
    if options.output is None:
        return None
    notes = [
        f"captured from {options.port} by {tool_version()} (passive: nothing written to the port)",
        f"low latency mode: {'on' if status.low_latency else 'not available'}; "
        f"latency timer: {status.latency_timer_ms if status.latency_timer_ms is not None else 'unknown'} ms",
        status.modem_note(),
        *([options.line_guessed] if options.line_guessed else []),
    ]
    return Recorder(options.output, CaptureInfo(options.line, TimingQuality.HOST, tuple(notes)), options.rotation)


def _queue(shared: _Shared, chunk: Chunk, skipped: _Skipped) -> _Skipped:
    """Queue ``chunk`` for decoding, after a mark of the reads dropped before it; a full queue
    drops it (never blocks: the reader must keep up with the port). Returns the reads dropped and
    not yet marked."""
    try:
        if skipped.reads:
            skipped.t_ns = chunk.t_end_ns
            shared.reads.put_nowait(skipped)
            skipped = _Skipped()
        shared.reads.put_nowait(chunk)
    except queue.Full:
        shared.behind_reads += 1
        skipped.reads += 1
        skipped.size += len(chunk.data)
    return skipped


def _read(source: SerialSource, recorder: Recorder | None, shared: _Shared, decode: bool) -> None:
    skipped = _Skipped()
    try:
        while not shared.stop.is_set():
            chunk = source.read(READ_TIMEOUT_S)
            if chunk is None:
                continue
            if recorder is not None:
                recorder.add(chunk)
            if decode:
                skipped = _queue(shared, chunk, skipped)
            source.delivered()
    except PortGoneError as exc:
        shared.gone = str(exc)
    except BaseException as exc:
        shared.failure = exc
    finally:
        shared.stop.set()


class _Session:
    """The main thread's side: decoding, statistics, the view, the stop conditions."""

    def __init__(self, options: CaptureOptions, status: PortStatus, recorder: Recorder | None,
                 shared: _Shared, out: TextIO, *, request: StopRequest | None = None) -> None:
        self.options, self.recorder, self.shared = options, recorder, shared
        self.request = request or StopRequest(shared.stop)
        self.decoder = Decoder(options.line, TimingQuality.HOST, response_timeout_ns=options.response_timeout_ns,
                               host_gap_ns=live_gap_ns(options.line, status))
        self.state = LiveState(options.port, options.line.format(), options.output,
                               "timing host (times are when the PC read the bytes)", advice=status.advice())
        self.view = LiveView(self.state) if options.mode == "view" else None
        if options.mode == "jsonl":
            out = whole_writes(out)
        sinks: list[Sink] = [JsonlView(out)] if options.mode == "jsonl" else [self.view] if self.view else []
        if options.pcap is not None:
            sinks.append(options.pcap)
        self.delivery = Delivery([*sinks, *options.streams], options.profiles)
        #: How long decoding waits for more reads: a viewer (or Wireshark) wants each frame at once,
        #: a terminal view four times a second.
        self._wait_s = STREAM_WAIT_S if options.streams or options.pcap else REFRESH_S
        self._next_render = self._last_drain = 0.0
        self.out = out
        self._counters: dict[str, int] | None = None
        #: The latest moment every read before it was decoded (the last tick's).
        self.heard_until_ns: int | None = None

    def run(self, source: SerialSource) -> None:
        self.delivery.start(self.options.port, CaptureInfo(self.options.line, TimingQuality.HOST), self.options.line)
        deadline = None if self.options.duration_s is None else time.monotonic() + self.options.duration_s
        next_counters = 0.0
        render: Callable[[], None] = lambda: None  # noqa: E731
        live = None
        if self.view is not None:
            statistics = self.delivery.statistics
            live = Live(self.view.render(statistics), console=Console(file=self.out), refresh_per_second=4,
                        transient=False)
            live.start()
            view = self.view
            render = lambda: live.update(view.render(statistics))  # noqa: E731
        try:
            while not self.shared.stop.is_set():
                self._drain(source)
                if time.monotonic() >= next_counters:
                    self._check_counters(source)
                    next_counters = time.monotonic() + COUNTERS_EVERY_S
                if self.recorder is not None and self.recorder.error is not None:
                    raise self.recorder.error
                if deadline is not None and time.monotonic() >= deadline:
                    break
                if self.options.pcap is not None and self.options.pcap.reader_gone:
                    break  # the pipe's reader (Wireshark) has stopped: the capture ends as at Ctrl-C
                if time.monotonic() >= self._next_render:
                    render()
                    self._next_render = time.monotonic() + REFRESH_S
            self._drain(source)
        finally:
            if live is not None:
                render()
                live.stop()

    def _drain(self, source: SerialSource) -> None:
        """Decode everything read since the last time, in one batch, once a refresh interval
        has passed (or, with a live viewer, as soon as something was read)."""
        self._wait_for_reads()
        heard_until_ns = source.heard_until_ns()  # before the queue is emptied: every read before it is in it
        items = []
        try:
            while True:
                items.append(self.shared.reads.get_nowait())
        except queue.Empty:
            pass
        if self.options.mode == "quiet":
            return
        chunks: list[Chunk] = []
        for item in items:
            if isinstance(item, _Skipped):
                self._restart(chunks, item)
                chunks = []
            else:
                chunks.append(item)
        if chunks:
            self._deliver(self.decoder.feed(ChunkBatch.from_chunks(chunks)))
        self._deliver(self.decoder.tick(heard_until_ns))
        self.heard_until_ns = heard_until_ns
        self.state.behind_reads = self.shared.behind_reads
        if self.options.streams:
            self.state.streams = "; ".join(cast(StreamSink, sink).live_status() for sink in self.options.streams)
        self.state.recorded_bytes = self.recorder.bytes_recorded if self.recorder is not None else 0

    def _wait_for_reads(self) -> None:
        if self._wait_s == REFRESH_S:
            self.shared.stop.wait(REFRESH_S)
            return
        # One round per interval, reads or not: the framer closes a frame the line has been quiet
        # after on a tick.
        wait = self._last_drain + self._wait_s - time.monotonic()
        if wait > 0:
            self.shared.stop.wait(wait)
        self._last_drain = time.monotonic()

    def _restart(self, before: list[Chunk], skipped: _Skipped) -> None:
        """Reads were skipped after ``before``: decode those, close what they leave open (a frame
        cut by the gap is truncated there, open requests get no verdict), say so, and decode
        what follows from a clean start instead of splicing bytes that were never adjacent."""
        if before:
            self._deliver(self.decoder.feed(ChunkBatch.from_chunks(before)))
        self._deliver(self.decoder.flush())
        with self._writing():
            self.delivery.gap(SkippedReads(skipped.reads, skipped.size, skipped.t_ns))

    @contextmanager
    def _writing(self) -> Iterator[None]:
        """A stop signal waits until the records written here are whole (see :class:`StopRequest`)."""
        self.request.writing = True
        try:
            yield
        finally:
            self.request.writing = False

    def _deliver(self, batches: list[MessageBatch]) -> None:
        with self._writing():
            for batch in batches:
                self.delivery.batch(batch)
                if self.options.mode == "jsonl":
                    self.out.flush()  # a script reading the pipe sees each frame at once

    def _check_counters(self, source: SerialSource) -> None:
        counters = source.counters()
        if counters is None:
            return
        errors: dict[str, int] = {
            k: counters[k] for k in ("frame", "parity", "overrun", "buf_overrun", "brk") if k in ICOUNT_FIELDS
        }
        if self._counters is not None and errors != self._counters:
            note = "UART error counters: " + ", ".join(f"{k} {v}" for k, v in errors.items())
            self.state.uart_errors = note.split(": ", 1)[1]
            if self.recorder is not None:
                self.recorder.add_note(note)
        self._counters = errors

    def finish(self) -> None:
        if self.options.mode == "quiet":
            return
        try:
            self._deliver(self.decoder.flush())
            with self._writing():
                self.delivery.finish()
        finally:
            for stream in self.options.streams:
                stream.close()
            if self.options.pcap is not None:
                self.options.pcap.close()


def _report(code: int, options: CaptureOptions, recorder: Recorder | None, shared: _Shared, err: Console) -> int:
    if shared.behind_reads:
        kept = "the recording has every byte" if recorder is not None else "they are lost (no -o recording)"
        err.print(f"warning: {options.port}: decoding fell behind and skipped {shared.behind_reads:,} reads "
                  f"(decoding started again after each gap; in JSON Lines a gap record marks it); {kept}")
    if recorder is not None:
        files = ", ".join(recorder.files)
        err.print(f"recorded {recorder.bytes_recorded:,} bytes to {files}")
        if recorder.error is not None:
            raise recorder.error
    if shared.failure is not None:
        raise shared.failure
    if shared.gone is not None:
        raise RtuSniffError(ErrorKind.PORT_GONE, f"the port went away ({shared.gone}); the recording is closed",
                            path=options.port)
    return code
