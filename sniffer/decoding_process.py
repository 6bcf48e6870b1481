"""Reading, framing and pairing in a child process, so that they and a view run on two cores.

An export spends more per frame building and writing messages than reading, framing and
pairing cost; in one process the two add up. Here a forked child runs
:class:`decoders.pipeline.Decoder` over the reader and sends each step (the chunks read, the
message batches they completed) through a pipe, pickled: columns, a few hundred bytes a frame
at most, their arrays' memory written as it lies (:mod:`sniffer.step_pipe`). A thread of the
parent receives them, up to :data:`RECEIVED_AHEAD` ahead of their use. The parent annotates
and runs the view, exactly as in one process, so the output is the same byte for byte.

The child is forked before the view starts any thread. It ignores Ctrl-C (the parent stops
it), and it ends when the parent stops reading (the pipe breaks) or kills it. Its failures come
back as the exception it raised (the same one-line errors for bad input, its traceback added as
a note), and the reader's warnings come back with its last message. Where ``os.fork`` is
missing, :func:`decoding_jobs` says one process.
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import threading
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import Generic, NoReturn, TypeVar, cast

from decoders.capture import ChunkBatch, joined_batches
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader
from sniffer.io.following import QUIET_NS
from sniffer.step_pipe import receive_item, send_item

#: Pipe buffer asked for (Linux; 64 KiB otherwise): about three batches, so that the child runs
#: ahead of the parent without a context switch per 64 KiB.
PIPE_SIZE = 1 << 20
#: Steps a thread of the parent receives ahead of their use, at most. A step is one to two MB
#: pickled, more than the pipe holds, so the parent reading it waits on the child writing the
#: rest, while three threads share two cores. Received by a thread of their own, the steps come
#: while the parent works.
RECEIVED_AHEAD = 2


Prepared = TypeVar("Prepared")
#: Work on framed and paired messages alone (no decodings), done where they are made.
Prepare = Callable[[MessageBatch], Prepared]


@dataclass(frozen=True)
class DecodingStep(Generic[Prepared]):
    """What one batch of chunks completed. ``chunks`` is ``None`` at the end (the framer's and
    matcher's leftovers), and when the view does not want the chunks; ``prepared``: what the
    ``prepare`` stage made of each batch (empty without one)."""

    chunks: ChunkBatch | None
    batches: list[MessageBatch]
    prepared: list[Prepared]


@dataclass(frozen=True)
class _Ended:
    warnings: list[str]


@dataclass(frozen=True)
class _Failed:
    error: BaseException
    child_traceback: str
    warnings: list[str]


def decoding_jobs(requested: str, *, follow: bool = False, paced: bool = False) -> int:
    """Processes to decode with: ``"1"``, ``"2"``, or ``"auto"`` (two where there are two cores
    for this process and ``os.fork``). Following a growing file decodes in one: the writer sets
    the pace, and Ctrl-C (sent to this process alone by ``kill -INT``) must reach the reader.
    A paced replay (``paced``: ``--speed``, or a viewer watching a file) decodes in one too: its
    pace bounds it, not the CPU, and its clock must start when this process reads its first
    batch, after waiting for a viewer to subscribe. A decoding process would start the clock at
    once and read on while this one waits, and the viewer would get the replay's first part in
    one burst."""
    if requested not in ("auto", "1", "2"):
        if not requested.isdigit() or int(requested) < 1:
            raise RtuSniffError(ErrorKind.USAGE, f"--jobs {requested}: give auto, or a number of processes")
        requested = "2"  # one capture is decoded in two processes at most (more: --each)
    if follow or paced:
        if requested == "2":
            why = ("--follow: a followed recording is decoded as it is written, in one process; leave --jobs out"
                   if follow else "a paced replay (--speed, or a live viewer watching a file): a replay is decoded "
                   "in one process, at its pace; leave --jobs out, or give --speed max")
            raise RtuSniffError(ErrorKind.USAGE, f"--jobs 2 with {why}")
        return 1
    if requested == "2" and not hasattr(os, "fork"):
        raise RtuSniffError(ErrorKind.USAGE, "--jobs 2: this platform cannot fork a decoding process "
                            "(Windows); use --jobs 1 or auto")
    if requested != "auto":
        return int(requested)
    if not hasattr(os, "fork"):
        return 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return 2 if cores >= 2 else 1


def decode_here(
    reader: CaptureReader, decoder: Decoder, prepare: Prepare[Prepared] | None = None, *,
    join: tuple[int, int] | None = None,
) -> Iterator[DecodingStep[Prepared]]:
    """The steps of decoding ``reader``, in this process; ``join``: its batches after the first
    joined up to that many chunks or bytes (:func:`~decoders.capture.joined_batches`; ``None``:
    as read). An empty batch says the source has been quiet (a followed recording,
    :data:`sniffer.io.following.QUIET`): what is open is closed.

    The first batch goes as read: the parent starts on it while the child reads and decodes the
    next, which it does faster than the parent uses them: the parent starts sooner than if the
    first batch were joined like the rest."""
    last_ns: int | None = None
    batches = reader.batches()
    for chunks in batches if join is None else _first_as_read(batches, *join):
        if not len(chunks):
            if last_ns is not None:
                yield _step(None, decoder.tick(last_ns + QUIET_NS), prepare)
            continue
        last_ns = int(chunks.t_end_ns[-1])
        yield _step(chunks, decoder.feed(chunks), prepare)
    warning = decoder.line_check.warning()
    if warning is not None:
        # Told with the reader's warnings (from the decoding process too: they travel with them).
        reader.warnings.append(warning)
    yield _step(None, decoder.flush(), prepare)


def _first_as_read(batches: Iterator[ChunkBatch], chunks: int, size: int) -> Iterator[ChunkBatch]:
    """The first of ``batches`` as read, the others joined (:func:`~decoders.capture.joined_batches`)."""
    first = next(batches, None)
    if first is not None:
        yield first
    yield from joined_batches(batches, chunks, size)


def _step(
    chunks: ChunkBatch | None, batches: list[MessageBatch], prepare: Prepare[Prepared] | None
) -> DecodingStep[Prepared]:
    return DecodingStep(chunks, batches, [] if prepare is None else [prepare(batch) for batch in batches])


class ChildDecoding(Generic[Prepared]):
    """The steps of decoding ``reader``, decoded in a child forked at once (``prepare`` runs
    there too). Iterate once; :meth:`close` (also when iterating stopped early or failed)
    stops the child."""

    def __init__(
        self, reader: CaptureReader, decoder: Decoder, *, with_chunks: bool, prepare: Prepare[Prepared] | None = None,
        join: tuple[int, int] | None = None,
    ) -> None:
        self._reader = reader
        self._receive, send = os.pipe()
        _widen(send)
        pid = os.fork()
        if pid == 0:
            os.close(self._receive)
            _child(send, decode_here(reader, decoder, prepare, join=join), reader, with_chunks)
        os.close(send)
        self._child = _Child(pid)
        #: The child's process id.
        self.pid = pid
        self._received: queue.Queue[DecodingStep[Prepared] | _Ended | _Failed | None] = queue.Queue(RECEIVED_AHEAD)
        # A daemon: a second Ctrl-C may end the parent before it waits for the thread.
        self._receiver = threading.Thread(target=self._receive_all, name="rtusniff-receive", daemon=True)

    def __iter__(self) -> Iterator[DecodingStep[Prepared]]:
        self._receiver.start()
        while True:
            item = self._received.get()
            if isinstance(item, DecodingStep):
                yield item
                continue
            if item is None:
                raise RtuSniffError(
                    ErrorKind.RUNTIME, f"the decoding process ended without a word ({self._child.wait()})"
                ) from None
            self._child.ended = True
            self._reader.warnings.extend(item.warnings)
            if isinstance(item, _Failed):
                item.error.add_note(f"in the decoding process:\n{item.child_traceback}")
                raise item.error
            return

    def close(self) -> None:
        """Stops the child (unless it said it ended) and the receiving thread; closes the pipe.
        Once: a second call does nothing (a file descriptor is never closed twice, its number may
        be another file's by then)."""
        self._child.stop()  # its end of the pipe closes: the thread's next receive ends
        while self._receiver.is_alive():
            with contextlib.suppress(queue.Empty):  # room for the thread's last item
                self._received.get(timeout=0.05)
        if self._receive >= 0:
            os.close(self._receive)
            self._receive = -1

    def _receive_all(self) -> None:
        """In the receiving thread: every item the child sends, then ``None`` if the pipe ended
        without the child's last word (or a failure, if one did not unpickle)."""
        while True:
            item: DecodingStep[Prepared] | _Ended | _Failed | None
            try:
                item = cast("DecodingStep[Prepared] | _Ended | _Failed", receive_item(self._receive))
            except (EOFError, OSError):
                item = None
            except Exception as exc:  # a step that does not unpickle here: the parent raises it
                item = _Failed(exc, traceback.format_exc(), [])
            self._received.put(item)
            if not isinstance(item, DecodingStep):
                return


class _Child:
    """The forked decoding process: waited for once, killed if it has not said it ended."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.ended = False
        self._status: int | None = None

    def wait(self) -> str:
        if self._status is None:
            self._status = os.waitpid(self.pid, 0)[1]
        if os.WIFSIGNALED(self._status):
            return f"killed by {signal.Signals(os.WTERMSIG(self._status)).name}"
        return f"exit status {os.waitstatus_to_exitcode(self._status)}"

    def stop(self) -> None:
        if not self.ended and self._status is None:
            os.kill(self.pid, signal.SIGKILL)
        self.wait()


def _child(
    send: int, steps: Iterator[DecodingStep[Prepared]], reader: CaptureReader, with_chunks: bool
) -> NoReturn:
    """Decode and send until done; never returns, never runs the parent's clean-up (``os._exit``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    code = 1
    try:
        code = _decode_and_send(send, steps, reader, with_chunks)
    except BaseException as exc:  # every failure goes to the parent, which reports it
        _report(send, exc, reader.warnings)
    finally:
        os._exit(code)


def _decode_and_send(
    send: int, steps: Iterator[DecodingStep[Prepared]], reader: CaptureReader, with_chunks: bool
) -> int:
    """0 when all is sent; 1 when the parent stopped reading (it has its own error to tell, or
    was interrupted). Only sending is guarded: an ``OSError`` of the reader is a failure to report."""
    for step in steps:
        if not _sent(send, step if with_chunks or step.chunks is None else replace(step, chunks=None)):
            return 1
    return 0 if _sent(send, _Ended(reader.warnings)) else 1


def _sent(send: int, item: object) -> bool:
    try:
        send_item(send, item)
    except OSError:
        return False
    return True


def _report(send: int, exc: BaseException, warnings: list[str]) -> None:
    failure = _Failed(exc, traceback.format_exc(), warnings)
    try:
        _sent(send, failure)
    except Exception:  # an exception that does not pickle: its text does
        _sent(send, _Failed(RuntimeError(f"{type(exc).__name__}: {exc}"), failure.child_traceback, warnings))


def _widen(send: int) -> None:
    try:
        import fcntl  # noqa: PLC0415 (POSIX only; the child process exists only where os.fork does)
    except ImportError:
        return
    setting = getattr(fcntl, "F_SETPIPE_SZ", None)
    if setting is not None:
        # A limit on pipe sizes (/proc/sys/fs/pipe-max-size) leaves the default: it works, slower.
        with contextlib.suppress(OSError):
            fcntl.fcntl(send, setting, PIPE_SIZE)
