"""``rtusniff cut``: a small capture of a window of a big one, cut at frame boundaries.

Two passes. The first frames the capture (no annotation) and finds the window's frames: their
indices, times and their bytes' place in the stream of the capture's bytes (every byte is in
exactly one frame or noise record, so a frame's place is the sum of the lengths before it).
The second reads the capture again and keeps exactly those bytes: whole chunks, and of a chunk
that holds a window's edge only the window's part. That part ends a whole number of characters
before the chunk, so its time is the chunk's less that many character times: the bytes of a
chunk are contiguous on the wire (``exact``) or taken so (``host``: a read's bytes end when it
returned), which is how the framer timed them in the whole capture, so the window's frames keep
their times (a ``host`` cut kept the read's time and moved the last frame by up to 11.5 ms).
UART errors and channels go with their bytes.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from decoders.capture import ChunkBatch
from decoders.frame import FrameFlag
from decoders.line import LineSettings
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from sniffer.selection import Selection, Window
from sniffer.sinks import Sink

REQUEST = ROLE_CODE[Role.REQUEST]


class PastWindow(Exception):  # noqa: N818 - a signal, not an error
    """Raised by :class:`WindowFinder` once the window is complete: no need to read further."""


@dataclass
class WindowPlace:
    """Where the window's frames are: indices, times, and their bytes' offsets in the capture."""

    first_index: int | None = None
    last_index: int | None = None
    t_first_ns: int = 0
    t_last_ns: int = 0
    byte_start: int = 0
    byte_end: int = 0
    #: Answers in the window whose requests lie before it, and retries whose first attempt does:
    #: analyzed alone, the cut cannot pair them or call them retries.
    answers_cut_off: int = 0
    retries_cut_off: int = 0

    def edges(self) -> str | None:
        """What the cut's edges split, said in its note and a warning; ``None`` when nothing."""
        parts = [f"{count} {what} whose {other} lie{'s' if count == 1 else ''} before it" for count, what, other in
                 ((self.answers_cut_off, "answer" if self.answers_cut_off == 1 else "answers", "request"),
                  (self.retries_cut_off, "retry" if self.retries_cut_off == 1 else "retries", "first attempt"))
                 if count]
        return f"the cut begins mid-exchange: {' and '.join(parts)}, which the cut alone does not pair" if parts \
            else None

    @property
    def frames(self) -> int:
        return 0 if self.first_index is None or self.last_index is None else self.last_index - self.first_index + 1


class WindowFinder(Sink):
    """Follows every framed batch and notes where the window's frames are (a ``--limit``
    keeps its first frames); raises :class:`PastWindow` when nothing later can be in it."""

    wants_frames = True

    def __init__(self, selection: Selection) -> None:
        self._window = Window(selection)
        self._limit = selection.limit
        self._offset = 0
        self.place = WindowPlace()
        #: Slaves asked in the window so far: a retry to one of them has its first attempt inside.
        self._asked: set[int] = set()

    def _edges(self, batch: MessageBatch, begin: int, end: int) -> None:
        """Count the window's answers and retries whose other half lies before the window."""
        first = self.place.first_index
        assert first is not None
        requests = batch.request_index[begin:end]
        self.place.answers_cut_off += int(((requests != NONE) & (requests < first)).sum())
        roles, slaves, flags = batch.role[begin:end].tolist(), batch.slave[begin:end].tolist(), \
            batch.flags[begin:end].tolist()
        for role, slave, flag in zip(roles, slaves, flags, strict=True):
            if role != REQUEST:
                continue
            if flag & FrameFlag.RETRY and slave not in self._asked:
                self.place.retries_cut_off += 1
            self._asked.add(slave)

    def missed(self) -> str | None:
        """Where the capture's frames lie, when the window held none (:meth:`Window.missed`)."""
        return self._window.missed()

    def frames(self, batch: MessageBatch) -> None:
        frames = batch.frames
        begin, end = self._window.span(batch)
        if self._limit is not None:
            end = min(end, begin + self._limit - self.place.frames)
        place = self.place
        if end > begin:
            if place.first_index is None:
                place.first_index = frames.first_index + begin
                place.t_first_ns = int(frames.t_start_ns[begin])
                place.byte_start = self._offset + int(frames.offsets[begin])
            place.last_index = frames.first_index + end - 1
            place.t_last_ns = int(frames.t_end_ns[end - 1])
            place.byte_end = self._offset + int(frames.offsets[end])
            self._edges(batch, begin, end)
        self._offset += len(frames.data)
        full = self._limit is not None and place.frames >= self._limit
        if (self._window.past or full) and place.first_index is not None:
            raise PastWindow


def window_chunks(batches: Iterator[ChunkBatch], place: WindowPlace, line: LineSettings) -> Iterator[ChunkBatch]:
    """The chunks of ``batches`` that hold the bytes ``[place.byte_start, place.byte_end)`` of the
    capture, the chunks at its edges cut to them (see the module docstring)."""
    offset = 0
    for batch in batches:
        size = len(batch.data)
        if offset + size > place.byte_start and offset < place.byte_end:
            yield _cut(batch, place.byte_start - offset, place.byte_end - offset, line)
        offset += size
        if offset >= place.byte_end:
            return


def _cut(batch: ChunkBatch, start: int, stop: int, line: LineSettings) -> ChunkBatch:
    """The bytes ``[start, stop)`` of ``batch`` (offsets in its data, clipped to it) as chunks."""
    start, stop = max(start, 0), min(stop, len(batch.data))
    ends = batch.ends
    first = int(np.searchsorted(ends, start, "right"))  # the chunk holding byte ``start``
    last = int(np.searchsorted(ends, stop, "left"))  # the chunk holding byte ``stop - 1``
    kept = batch.slice(first, last + 1)
    base = int(ends[first - 1]) if first else 0
    new_ends = np.minimum(kept.ends + base, stop) - start
    # The last chunk loses the bytes after ``stop``: its kept bytes ended that many characters earlier.
    dropped = int(ends[last]) - stop
    times = kept.t_end_ns.copy()
    if dropped:
        times[-1] -= round(dropped * line.char_time_ns)
    kinds = None if kept.uart_errors is None else kept.uart_errors[start - base : stop - base]
    return ChunkBatch(kept.data[start - base : stop - base], new_ends, times,
                      kinds if kinds is not None and kinds.any() else None, kept.channels)
