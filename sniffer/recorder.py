"""Recording a live capture: in a thread of its own, durable at least every second.

The reader hands chunks over without waiting (a deque); the recorder writes them as
one block per flush interval and makes the file durable (fsync). Ctrl-C, SIGTERM or
a vanished port end in :meth:`Recorder.stop`, which writes the rest and closes the
file properly; a killed process leaves a file readable up to its last flush; a
failed write (full disk) cuts the file back to its last durable size, so it stays
readable, and stops the recording.
"""

from __future__ import annotations

import contextlib
import os
import re
import threading
import time
from collections import deque
from dataclasses import dataclass

from decoders.capture import CaptureInfo, Chunk, ChunkBatch
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureWriter
from sniffer.io.registry import open_writer
from sniffer.io.rotation import rotated_path

FLUSH_INTERVAL_S = 1.0
_SIZE_UNITS = {"": 1, "b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9}
_TIME_UNITS = {"s": 1, "m": 60, "h": 3600, "d": 86400}


@dataclass(frozen=True)
class Rotation:
    """Start a new file after ``max_bytes`` or ``max_seconds``."""

    max_bytes: int | None = None
    max_seconds: float | None = None

    @classmethod
    def parse(cls, text: str) -> Rotation:
        """``100MB``, ``1GB``, ``500kB`` or ``30s``, ``15m``, ``1h``, ``1d``."""
        match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([a-zA-Z]*)\s*", text)
        unit = match.group(2).lower() if match else ""
        if match and unit in _TIME_UNITS:
            return cls(max_seconds=float(match.group(1)) * _TIME_UNITS[unit])
        if match and unit in _SIZE_UNITS and float(match.group(1)) > 0:
            return cls(max_bytes=int(float(match.group(1)) * _SIZE_UNITS[unit]))
        raise RtuSniffError(ErrorKind.USAGE, f"--rotate {text}: give a size (100MB, 1GB) or a duration (30m, 1h, 1d)")


class Recorder:
    """Writes handed-over chunks to disk from its own thread."""

    def __init__(self, path: str, info: CaptureInfo, rotation: Rotation | None = None,
                 flush_interval_s: float = FLUSH_INTERVAL_S) -> None:
        self.path = path
        self.info = info
        self.rotation = rotation
        self.flush_interval_s = flush_interval_s
        self.files: list[str] = []
        self.bytes_recorded = 0
        self.error: RtuSniffError | None = None
        self._pending: deque[Chunk] = deque()
        self._notes: deque[str] = deque()
        self._stop = threading.Event()
        self._writer: CaptureWriter | None = None
        self._opened_at = 0.0
        self._durable_size = 0
        self._open_next()
        self._thread = threading.Thread(target=self._run, name="rtusniff-recorder", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def add(self, chunk: Chunk) -> None:
        """Hand a chunk over; never blocks."""
        self._pending.append(chunk)

    def add_note(self, note: str) -> None:
        self._notes.append(note)

    def stop(self) -> None:
        """Write what is left and close the file properly."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        else:
            self._write_pending()
        if self._writer is not None and self.error is None:
            self._writer.close()
            self._writer = None

    @property
    def current_file(self) -> str:
        return self.files[-1]

    def _open_next(self) -> None:
        path = rotated_path(self.path, len(self.files) + 1) if self.rotation else self.path
        self._writer = open_writer(path, self.info)
        self.files.append(path)
        self._opened_at = time.monotonic()
        self._durable_size = 0

    def _run(self) -> None:
        while not self._stop.wait(self.flush_interval_s):
            if not self._write_pending():
                return
        self._write_pending()

    def _write_pending(self) -> bool:
        chunks = [self._pending.popleft() for _ in range(len(self._pending))]
        notes = [self._notes.popleft() for _ in range(len(self._notes))]
        writer = self._writer
        if writer is None or (not chunks and not notes):
            return True
        try:
            if notes:
                writer.add_notes(notes)
            if chunks:
                writer.write_batch(ChunkBatch.from_chunks(chunks))
            writer.flush()
        except OSError as exc:
            self._fail(exc)
            return False
        self.bytes_recorded += sum(len(c.data) for c in chunks)
        self._durable_size = writer.size
        if self._rotation_due(writer):
            writer.close()
            try:
                self._open_next()
            except RtuSniffError as exc:  # the next name was taken meanwhile: never written over
                self._writer = None
                self.error = exc
                return False
        return True

    def _rotation_due(self, writer: CaptureWriter) -> bool:
        if self.rotation is None:
            return False
        limits = self.rotation
        too_big = limits.max_bytes is not None and writer.size >= limits.max_bytes
        too_old = limits.max_seconds is not None and time.monotonic() - self._opened_at >= limits.max_seconds
        return too_big or too_old

    def _fail(self, exc: OSError) -> None:
        """A write failed (disk full): keep the file as it was at its last flush."""
        path = self.current_file
        self.error = RtuSniffError(ErrorKind.OUTPUT_FAILED,
                                   f"writing failed ({exc.strerror}); the recording is kept up to its last flush "
                                   f"({self._durable_size} bytes)", path=path)
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.abandon()
        with contextlib.suppress(OSError):
            os.truncate(path, self._durable_size)
