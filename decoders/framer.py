"""The framer: frames from timing where timing can be trusted, from content elsewhere.

Timing (numpy over byte times) cuts the stream into segments at silences that
certainly separate frames: t3.5 on an ``exact`` capture, ``host_gap_ns`` on a
``host`` one (a USB adapter delivers bytes late and in bursts, so shorter gaps say
nothing). :func:`decoders.framing.content.parse_segment` then cuts each segment
into frames and noise by length rules and CRC. Every byte ends up in exactly one
frame or noise record.

Flags: ``gap_1_5`` on a silence > t1.5 inside a frame and ``short_idle`` on a frame
whose silence before it was < t3.5, both only where timing is ``exact``;
``truncated`` and ``bad_length`` come from the content pass.

Timestamps have 1 ns resolution and byte times are rounded to it, so thresholds
are compared with 1 ns of allowance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.byte_times import byte_times
from decoders.capture import ChunkBatch, Int64Array, TimingQuality
from decoders.crc import crc_ok_many
from decoders.frame import NO_IDLE, FrameBatch, FrameFlag
from decoders.framing.content import OPEN_LOOKAHEAD, OpenRequest, Piece, after_frame, parse_segment
from decoders.framing.fast import single_frame_segments
from decoders.line import LineSettings
from decoders.modbus.layouts import MAX_ADU

#: Rounding allowance when comparing integer-ns silences with fractional thresholds.
TOLERANCE_NS = 1.0
#: On host-timed captures, the silence that certainly separates frames: well above
#: a USB adapter's latency timer (16 ms by default) and the host's scheduling jitter.
DEFAULT_HOST_GAP_NS = 100_000_000
#: An open segment longer than this is parsed before its end is known.
OPEN_PARSE_BYTES = OPEN_LOOKAHEAD + MAX_ADU


@dataclass
class _Pieces:
    """Pieces in columns, in wire order; offsets index the framer's byte buffer."""

    first: Int64Array
    last: Int64Array
    is_noise: npt.NDArray[np.bool_]
    crc_ok: npt.NDArray[np.bool_]
    flags: npt.NDArray[np.uint16]
    protocol: npt.NDArray[np.uint8]

    @classmethod
    def of(cls, pieces: list[Piece]) -> _Pieces:
        count = len(pieces)
        return cls(
            np.fromiter((p.start for p in pieces), np.int64, count),
            np.fromiter((p.end for p in pieces), np.int64, count),
            np.fromiter((p.is_noise for p in pieces), np.bool_, count),
            np.fromiter((p.crc_ok for p in pieces), np.bool_, count),
            np.fromiter((p.flags for p in pieces), np.uint16, count),
            np.fromiter((p.protocol for p in pieces), np.uint8, count),
        )

    @classmethod
    def join(cls, parts: list[_Pieces]) -> _Pieces:
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in _PIECE_COLUMNS))


_PIECE_COLUMNS = ("first", "last", "is_noise", "crc_ok", "flags", "protocol")
#: How many frames back the open request is replayed from before a segment that the
#: content parser handles (only a run of echo frames longer than this could mislead it).
REPLAY_FRAMES = 4


class Framer:
    """Splits a byte stream into frames and noise; ``feed`` batches in order, then ``flush``.

    Held back between calls: the open segment, bounded by ``OPEN_PARSE_BYTES`` plus
    one batch.
    """

    def __init__(
        self,
        line: LineSettings,
        timing: TimingQuality = TimingQuality.EXACT,
        host_gap_ns: int = DEFAULT_HOST_GAP_NS,
    ) -> None:
        self.line = line
        self.timing = timing
        self._boundary_ns = line.t3_5_ns - TOLERANCE_NS if timing is TimingQuality.EXACT else float(host_gap_ns)
        self._data = b""
        self._starts: Int64Array = np.zeros(0, np.int64)
        self._ends: Int64Array = np.zeros(0, np.int64)
        self._at_capture_start = True
        self._open_request: OpenRequest = None
        self._next_index = 0
        self._last_end_ns: int | None = None

    def feed(self, batch: ChunkBatch) -> FrameBatch:
        """Frames and noise that ``batch`` completes."""
        new_starts, new_ends = byte_times(batch, self.line.char_time_ns)
        data = self._data + batch.data
        starts = np.concatenate([self._starts, new_starts])
        ends = np.concatenate([self._ends, new_ends])
        cuts = np.flatnonzero(starts[1:] - ends[:-1] >= self._boundary_ns) + 1
        bounds = np.concatenate([np.zeros(1, np.int64), cuts])
        parts = [self._closed_segments(data, bounds)]
        open_start = int(bounds[-1])
        kept_from = open_start
        if len(data) - open_start > OPEN_PARSE_BYTES:
            open_pieces = self._parse(data, open_start, len(data), closed=False)
            parts.append(_Pieces.of(open_pieces))
            kept_from = open_pieces[-1].end if open_pieces else open_start
        self._data, self._starts, self._ends = data[kept_from:], starts[kept_from:], ends[kept_from:]
        return self._assemble(data, starts, ends, _Pieces.join(parts))

    def close_idle(self, now_ns: int) -> FrameBatch:
        """Live capture: the open segment is closed once the line has been quiet for as
        long as a boundary needs (t3.5, or the host gap), without waiting for a next byte."""
        if not self._data or now_ns - int(self._ends[-1]) < self._boundary_ns:
            return self._assemble(b"", self._starts[:0], self._ends[:0], _Pieces.of([]))
        data, starts, ends = self._data, self._starts, self._ends
        self._data, self._starts, self._ends = b"", np.zeros(0, np.int64), np.zeros(0, np.int64)
        return self._assemble(data, starts, ends, _Pieces.of(self._parse(data, 0, len(data), closed=True)))

    def flush(self) -> FrameBatch:
        """Everything still held, at the end of the capture."""
        data, starts, ends = self._data, self._starts, self._ends
        self._data, self._starts, self._ends = b"", np.zeros(0, np.int64), np.zeros(0, np.int64)
        pieces = self._parse(data, 0, len(data), closed=True, at_end=True) if data else []
        return self._assemble(data, starts, ends, _Pieces.of(pieces))

    def _closed_segments(self, data: bytes, bounds: Int64Array) -> _Pieces:
        """Pieces of the segments ``data[bounds[i]:bounds[i+1]]``: whole frames in bulk,
        the rest through the content parser."""
        seg_starts, seg_ends = bounds[:-1], bounds[1:]
        count = len(seg_starts)
        single = single_frame_segments(data, seg_starts, seg_ends, crc_ok_many(data, bounds))
        slow = np.flatnonzero(~single).tolist()
        parsed: list[list[Piece]] = []
        done = 0
        for index in slow:
            if index > 0:
                self._at_capture_start = False  # whole frames came before it
            self._open_request = self._replay(data, seg_starts, seg_ends, done, index)
            parsed.append(self._parse(data, int(seg_starts[index]), int(seg_ends[index]), closed=True))
            done = index + 1
        self._open_request = self._replay(data, seg_starts, seg_ends, done, count)
        if count:
            self._at_capture_start = False
        per_segment = np.ones(count, np.int64)
        per_segment[slow] = [len(p) for p in parsed]
        position = np.cumsum(per_segment) - per_segment
        total = int(per_segment.sum())
        columns = _Pieces(
            np.empty(total, np.int64), np.empty(total, np.int64), np.zeros(total, np.bool_),
            np.ones(total, np.bool_), np.zeros(total, np.uint16), np.zeros(total, np.uint8),
        )
        columns.first[position[single]] = seg_starts[single]
        columns.last[position[single]] = seg_ends[single]
        if parsed:
            slow_pieces = _Pieces.of([p for pieces in parsed for p in pieces])
            slots = np.concatenate([position[i] + np.arange(len(p)) for i, p in zip(slow, parsed, strict=True)])
            for name in _PIECE_COLUMNS:
                getattr(columns, name)[slots] = getattr(slow_pieces, name)
        return columns

    def _replay(self, data: bytes, seg_starts: Int64Array, seg_ends: Int64Array, begin: int, stop: int) -> OpenRequest:
        """The open request after the whole-frame segments ``begin..stop-1``."""
        first = max(begin, stop - REPLAY_FRAMES)
        state = self._open_request if first == begin else None
        for k in range(first, stop):
            state = after_frame(data[int(seg_starts[k]) : int(seg_ends[k])], state)
        return state

    def _parse(self, data: bytes, begin: int, stop: int, *, closed: bool, at_end: bool = False) -> list[Piece]:
        parse = parse_segment(
            data[begin:stop],
            closed=closed,
            at_capture_start=self._at_capture_start,
            at_capture_end=at_end,
            open_request=self._open_request,
        )
        if parse.pieces:
            self._at_capture_start = False
            self._open_request = parse.open_request
        return [Piece(p.start + begin, p.end + begin, p.is_noise, p.crc_ok, p.flags, p.protocol) for p in parse.pieces]

    def _assemble(self, data: bytes, starts: Int64Array, ends: Int64Array, pieces: _Pieces) -> FrameBatch:
        first, last, is_noise, flags = pieces.first, pieces.last, pieces.is_noise, pieces.flags.copy()
        count = len(first)
        if count:
            # Earliest start and latest end of the bytes: the same as first and last on a
            # consistent capture, and still ordered on one whose times overlap.
            span = slice(int(first[0]), int(last[-1]))
            t_start = np.minimum.reduceat(starts[span], first - first[0])
            t_end = np.maximum.reduceat(ends[span], first - first[0])
        else:
            t_start = t_end = np.zeros(0, np.int64)
        idle = np.empty(count, np.int64)
        if count:
            idle[1:] = t_start[1:] - t_end[:-1]
            idle[0] = NO_IDLE if self._last_end_ns is None else t_start[0] - self._last_end_ns
            self._last_end_ns = int(t_end[-1])
        if self.timing is TimingQuality.EXACT:
            flags |= self._timing_flags(starts, ends, first=first, last=last, idle=idle, is_noise=is_noise)
        else:
            # Host times are estimates; a negative silence is an artefact of them.
            idle[(idle < 0) & (idle != NO_IDLE)] = 0
        offsets = np.zeros(count + 1, np.int64)
        offsets[1:] = np.cumsum(last - first)
        frame_data = data[int(first[0]) : int(last[-1])] if count else b""
        batch = FrameBatch(
            first_index=self._next_index,
            data=frame_data,
            offsets=offsets,
            t_start_ns=t_start,
            t_end_ns=t_end,
            crc_ok=pieces.crc_ok,
            flags=flags,
            is_noise=is_noise,
            idle_before_ns=idle,
            protocol=pieces.protocol if pieces.protocol.any() else None,
        )
        self._next_index += count
        return batch

    def _timing_flags(
        self,
        starts: Int64Array,
        ends: Int64Array,
        *,
        first: Int64Array,
        last: Int64Array,
        idle: Int64Array,
        is_noise: npt.NDArray[np.bool_],
    ) -> npt.NDArray[np.uint16]:
        # gaps_upto[k]: how many of bytes 0..k-1 follow a silence > t1.5; a frame
        # [first, last) has one inside if any of its bytes after the first does.
        gaps_upto = np.zeros(len(starts) + 1, np.int64)
        gaps_upto[2:] = np.cumsum(starts[1:] - ends[:-1] > self.line.t1_5_ns + TOLERANCE_NS)
        has_gap = gaps_upto[last] - gaps_upto[first + 1] > 0
        short = (idle != NO_IDLE) & (idle < self.line.t3_5_ns - TOLERANCE_NS)
        flags = np.where(has_gap & ~is_noise, FrameFlag.GAP_1_5, 0)
        flags |= np.where(short & ~is_noise, FrameFlag.SHORT_IDLE, 0)
        return flags.astype(np.uint16)
