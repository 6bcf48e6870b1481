"""Stopping on a signal: every command cleans up on SIGTERM as on Ctrl-C; a capture stops
without cutting a record in two, and its writes are never cut.

:func:`terminate_raises`: SIGTERM (``kill PID``, a service manager stopping a job) raises
:class:`TerminatedError` where the default would end the process at once, so that what a
command was writing is abandoned or closed as on Ctrl-C (no ``.partial`` file is left); SIGINT
raises ``KeyboardInterrupt`` in every command, also where a shell started it ignored.

SIGINT and SIGTERM stop a live capture at once, except while records are being written: then the
first signal stops it once the write is done (:class:`StopRequest`). A write interrupted by a
signal is finished by :class:`WholeWrites`. Signal handlers are set only where Python allows
(the main thread); the signals used here exist on Windows too.
"""

from __future__ import annotations

import io
import os
import signal
import threading
from collections.abc import Callable
from types import FrameType
from typing import TextIO, cast

#: Exit codes after Ctrl-C and SIGTERM (128 + the signal's number, as shells report them).
INTERRUPTED = 130
TERMINATED = 143


class TerminatedError(Exception):
    """SIGTERM arrived."""


_SignalHandler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None


class WholeWrites(io.TextIOBase):
    """Text written straight to a file descriptor, every byte of it. A stop signal that interrupts a
    large write to a full pipe (a slow consumer) makes CPython's buffered writer drop part of the
    data even when the handler returns (seen on 3.11: 74 of 2 000 lines lost); ``os.write`` says
    how much it wrote, and the rest is written after it."""

    def __init__(self, fd: int) -> None:
        self._fd = fd

    def write(self, text: str) -> int:
        view = memoryview(text.encode())
        while view:
            view = view[os.write(self._fd, view) :]
        return len(text)

    def writable(self) -> bool:
        return True


def whole_writes(out: TextIO) -> TextIO:
    """``out``, or for a stream on a file descriptor, a writer that never drops what it is given."""
    try:
        fd = out.fileno()
    except (OSError, ValueError, AttributeError):  # a StringIO, a stream without a descriptor
        return out
    out.flush()
    return cast(TextIO, WholeWrites(fd))


class StopRequest:
    """SIGINT raises KeyboardInterrupt and SIGTERM TerminatedError, at once, except while records
    are being written: a JSON Lines record cut in two is a line no script can read. Then the first
    signal asks for a stop once the write is done, and a second one raises (a consumer that never
    reads again must not keep the capture from stopping)."""

    def __init__(self, stop: threading.Event) -> None:
        """``stop``: set when a signal asks for a stop after the write."""
        self.stop = stop
        self.writing = False
        self.asked: int | None = None

    def handle(self, signum: int, frame: FrameType | None) -> None:
        if self.writing and self.asked is None:
            self.asked = signum
            self.stop.set()
            return
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise TerminatedError


def terminate_raises() -> dict[int, _SignalHandler]:
    """SIGTERM raises :class:`TerminatedError` from now on, and SIGINT ``KeyboardInterrupt`` even
    where the process started with it ignored (a shell script's background job: ``kill -INT``
    must stop an ``export &`` as it stops a capture); the main thread only. The previous
    handlers, for :func:`restore_signals`."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {signal.SIGTERM: signal.signal(signal.SIGTERM, _raise_terminated),
            signal.SIGINT: signal.signal(signal.SIGINT, signal.default_int_handler)}


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise TerminatedError


def handle_stop_signals(request: StopRequest) -> dict[int, _SignalHandler]:
    """``request`` handles SIGINT and SIGTERM; the previous handlers, to restore. Only the main
    thread may set handlers (tests run captures in threads too)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {
        signal.SIGINT: signal.signal(signal.SIGINT, request.handle),
        signal.SIGTERM: signal.signal(signal.SIGTERM, request.handle),
    }


def restore_signals(previous: dict[int, _SignalHandler]) -> None:
    for number, handler in previous.items():
        if handler is not None:  # None: set outside Python, cannot be put back
            signal.signal(number, handler)
