"""``rtusniff cut``: a small capture of a window of a big one, cut at frame boundaries.

Two passes. The first frames the capture (no annotation) and finds the window's frames: their
indices, times and their bytes' place in the stream of the capture's bytes (every byte is in
exactly one frame or noise record, so a frame's place is the sum of the lengths before it).
The second reads the capture again and keeps exactly those bytes: whole chunks, and of a chunk
that holds a window's edge only the window's part. That part ends a whole number of characters
before the chunk, so its time is the chunk's less that many character times: the bytes of a
chunk are contiguous on the wire (``exact``) or taken so (``host``: a read's bytes end when it
returned), which is how the framer timed them in the whole capture, so the window's frames keep
their times (a ``host`` cut that kept the read's time would move its last frame).
UART errors and channels go with their bytes.

A window alone may decode otherwise than in the whole capture: an answer whose request lies
before it, a retry whose first attempt does, a timeout a later frame decides, a damaged frame its
neighbours place. The first pass therefore notes up to ``CONTEXT`` frames on each side and what
the whole capture's decoding said of every window frame; :func:`reproducing_context` decodes the
window with ever more context (fewest frames first, those before first) until its frames come
out alike, and the cut holds that context.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from decoders.capture import ChunkBatch
from decoders.frame import FrameFlag
from decoders.line import LineSettings
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from decoders.pipeline import Decoder
from sniffer.selection import Selection, Window
from sniffer.sinks import Sink

REQUEST = ROLE_CODE[Role.REQUEST]
#: Frames of context a cut may take on each side of its window to decode as in the whole capture.
CONTEXT = 16
#: A request index no decoding of a cut gives: the request lies before the cut.
OUTSIDE = -2
#: A frame's length, role, flags, request index and latency.
Verdict = tuple[int, int, int, int, int]


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
    #: Retries in the window whose first attempt lies before it: analyzed alone, the cut cannot
    #: call them retries (its answers whose requests lie before it, the verdicts say).
    retries_cut_off: int = 0
    #: The byte spans of up to ``CONTEXT`` frames before and after the window, in wire order.
    before: list[tuple[int, int]] = field(default_factory=list)
    after: list[tuple[int, int]] = field(default_factory=list)
    #: What the whole capture's decoding said of each window frame: length, role, flags,
    #: request (absolute index or ``NONE``) and latency.
    verdicts: list[Verdict] = field(default_factory=list)

    def edges(self) -> str | None:
        """What the cut's edges split, said in its note and a warning; ``None`` when nothing."""
        assert self.first_index is not None
        answers = sum(request != NONE and request < self.first_index for *_, request, _ in self.verdicts)
        parts = [f"{count} {what} whose {other} lie{'s' if count == 1 else ''} before it" for count, what, other in
                 ((answers, "answer" if answers == 1 else "answers", "request"),
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
        self._recent: deque[tuple[int, int]] = deque(maxlen=CONTEXT)

    def _count_retries(self, batch: MessageBatch, begin: int, end: int) -> None:
        """Count the window's retries whose first attempt lies before the window."""
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
        place = self.place
        complete = place.first_index is not None and (self._window.past or self._full())
        begin, end = (0, 0) if complete else self._window.span(batch)
        if self._limit is not None:
            end = min(end, begin + self._limit - place.frames)
        spans = list(pairwise((self._offset + frames.offsets).tolist()))  # each frame's bytes in the capture
        if end > begin:
            if place.first_index is None:
                place.first_index = frames.first_index + begin
                place.t_first_ns = int(frames.t_start_ns[begin])
                place.byte_start = spans[begin][0]
                place.before = [*self._recent, *spans[:begin]][-CONTEXT:]
            place.last_index = frames.first_index + end - 1
            place.t_last_ns = int(frames.t_end_ns[end - 1])
            place.byte_end = spans[end - 1][1]
            self._count_retries(batch, begin, end)
            place.verdicts += zip(np.diff(frames.offsets[begin : end + 1]).tolist(), batch.role[begin:end].tolist(),
                                  batch.flags[begin:end].tolist(), batch.request_index[begin:end].tolist(),
                                  batch.latency_ns[begin:end].tolist(), strict=True)
        if place.first_index is None:
            self._recent.extend(spans)
        elif self._window.past or self._full():
            place.after += spans[end:][: CONTEXT - len(place.after)]
        self._offset += len(frames.data)
        if place.first_index is not None and (self._window.past or self._full()) and len(place.after) >= CONTEXT:
            raise PastWindow

    def _full(self) -> bool:
        return self._limit is not None and self.place.frames >= self._limit


def window_chunks(batches: Iterator[ChunkBatch], span: tuple[int, int], line: LineSettings) -> Iterator[ChunkBatch]:
    """The chunks of ``batches`` that hold the bytes ``[start, end)`` of the capture, the chunks
    at its edges cut to them (see the module docstring)."""
    start, end = span
    offset = 0
    for batch in batches:
        size = len(batch.data)
        if offset + size > start and offset < end:
            yield cut_batch(batch, start - offset, end - offset, line)
        offset += size
        if offset >= end:
            return


def cut_batch(batch: ChunkBatch, start: int, stop: int, line: LineSettings) -> ChunkBatch:
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


#: Windows of up to this many frames are searched for the context that reproduces them.
SEARCHED_FRAMES = 400


@dataclass(frozen=True)
class Context:
    """Frames taken before and after the window so that the cut decodes as the whole capture
    did: ``before`` and ``after`` frames; ``reproduces``: whether any such context was found."""

    before: int = 0
    after: int = 0
    reproduces: bool = True

    def span(self, place: WindowPlace) -> tuple[int, int]:
        """The bytes of the capture the cut holds."""
        start = place.before[len(place.before) - self.before][0] if self.before else place.byte_start
        end = place.after[self.after - 1][1] if self.after else place.byte_end
        return start, end


def reproducing_context(place: WindowPlace, held: ChunkBatch, held_from: int, line: LineSettings,
                        decoder: Callable[[], Decoder]) -> Context:
    """The least context (fewest frames, those before first) with which the bytes ``held``
    (from byte ``held_from`` of the capture) decode to the window's verdicts: every frame of the
    window with its length, role, flags, request and latency. No context, not reproducing, when
    none of up to ``CONTEXT`` frames a side does (the caller searches windows of up to
    :data:`SEARCHED_FRAMES`)."""
    for extra in range(len(place.before) + len(place.after) + 1):
        for before in range(min(extra, len(place.before)) + 1):
            after = extra - before
            if after > len(place.after):
                continue
            context = Context(before, after)
            start, end = context.span(place)
            got = _verdicts(cut_batch(held, start - held_from, end - held_from, line), decoder())
            if got[before : before + len(place.verdicts)] == _relative(place, before):
                return context
    return Context(reproduces=False)


def _relative(place: WindowPlace, before: int) -> list[Verdict]:
    """The window's verdicts with requests counted from the cut's first frame."""
    assert place.first_index is not None
    shift = place.first_index - before
    # A request before the cut has no index in it: a value no decoding gives (NONE is -1).
    return [(size, role, flags, NONE if request == NONE else request - shift if request >= shift else OUTSIDE, latency)
            for size, role, flags, request, latency in place.verdicts]


def _verdicts(batch: ChunkBatch, decoder: Decoder) -> list[Verdict]:
    """Every frame's verdict when ``batch`` is decoded alone, in frame order."""
    rows: list[Verdict] = []
    for decoded in (*decoder.feed(batch), *decoder.flush()):
        rows += zip(np.diff(decoded.frames.offsets).tolist(), decoded.role.tolist(), decoded.flags.tolist(),
                    decoded.request_index.tolist(), decoded.latency_ns.tolist(), strict=True)
    return rows
