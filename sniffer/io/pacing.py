"""Replaying a capture at its own speed (``--speed``): the chunks come when their time comes.

A live viewer (``--foxglove``, ``--rerun``) given a file should see the traffic unfold as it
did on the wire, or ``--speed`` times faster, not a day in a second. :class:`PacedReader`
wraps any capture reader: each batch is cut into slices of at most ``SLICE_S`` of wall time
and a slice is handed on once the wall clock reaches the capture time of its last chunk
(counted from the first chunk of the capture, divided by the speed). Long silences on the
bus are waited out, not skipped, as a replay should.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import numpy as np

from decoders.capture import CaptureInfo, ChunkBatch
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader

#: Wall time per slice: a viewer sees frames every 50 ms at most apart, at any speed.
SLICE_S = 0.05


def parse_speed(text: str) -> float | None:
    """``--speed``: a factor (``1``, ``10``, ``0.5``) or ``max`` (no pacing: ``None``)."""
    if text.strip().lower() == "max":
        return None
    try:
        speed = float(text)
    except ValueError:
        speed = -1.0
    if not speed > 0 or speed == float("inf"):
        raise RtuSniffError(ErrorKind.USAGE, f"--speed {text}: give a factor above 0 (1: as recorded, 10: ten times "
                            "faster) or 'max' (as fast as it decodes)")
    return speed


class PacedReader:
    """``reader``'s batches, each slice held until its time (see the module docstring)."""

    def __init__(self, reader: CaptureReader, speed: float, *, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self._reader, self._speed = reader, speed
        self._clock, self._sleep = clock, sleep
        self.info: CaptureInfo = reader.info
        #: The reader's own lists (filled as it reads).
        self.late_notes: list[str] = reader.late_notes
        self.warnings: list[str] = reader.warnings
        #: The capture time and the wall time the replay counts from (its first chunk).
        self._origin: tuple[int, float] | None = None

    def last_time_ns(self) -> int | None:
        return self._reader.last_time_ns()

    def close(self) -> None:
        self._reader.close()

    def batches(self) -> Iterator[ChunkBatch]:
        for batch in self._reader.batches():
            yield from self._slices(batch)

    def _slices(self, batch: ChunkBatch) -> Iterator[ChunkBatch]:
        if not len(batch):
            return
        if self._origin is None:
            self._origin = (int(batch.t_end_ns[0]), self._clock())
        t0, wall0 = self._origin
        step_ns = int(SLICE_S * self._speed * 1e9)
        # Chunk positions where a new slice starts: every step of capture time.
        slots = (batch.t_end_ns - t0) // max(step_ns, 1)
        cuts = np.flatnonzero(np.diff(slots)) + 1
        starts = [0, *cuts.tolist()]
        stops = [*cuts.tolist(), len(batch)]
        for start, stop in zip(starts, stops, strict=True):
            due = wall0 + (int(batch.t_end_ns[stop - 1]) - t0) / 1e9 / self._speed
            wait = due - self._clock()
            if wait > 0:
                self._sleep(wait)
            yield batch.slice(start, stop)
