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

import numpy as np
import numpy.typing as npt

from decoders.byte_times import byte_times
from decoders.capture import ChunkBatch, Int64Array, TimingQuality
from decoders.frame import NO_IDLE, FrameBatch, FrameFlag
from decoders.framing.content import OPEN_LOOKAHEAD, OpenRequest, Piece, parse_segment
from decoders.line import LineSettings
from decoders.modbus.layouts import MAX_ADU

#: Rounding allowance when comparing integer-ns silences with fractional thresholds.
TOLERANCE_NS = 1.0
#: On host-timed captures, the silence that certainly separates frames: well above
#: a USB adapter's latency timer (16 ms by default) and the host's scheduling jitter.
DEFAULT_HOST_GAP_NS = 100_000_000
#: An open segment longer than this is parsed before its end is known.
OPEN_PARSE_BYTES = OPEN_LOOKAHEAD + MAX_ADU


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
        bounds = [0, *cuts.tolist()]
        pieces: list[Piece] = []
        for begin, stop in zip(bounds[:-1], bounds[1:], strict=True):
            pieces.extend(self._parse(data, begin, stop, closed=True))
        open_start = bounds[-1]
        kept_from = open_start
        if len(data) - open_start > OPEN_PARSE_BYTES:
            open_pieces = self._parse(data, open_start, len(data), closed=False)
            pieces.extend(open_pieces)
            kept_from = open_pieces[-1].end if open_pieces else open_start
        self._data, self._starts, self._ends = data[kept_from:], starts[kept_from:], ends[kept_from:]
        return self._assemble(data, starts, ends, pieces)

    def flush(self) -> FrameBatch:
        """Everything still held, at the end of the capture."""
        data, starts, ends = self._data, self._starts, self._ends
        self._data, self._starts, self._ends = b"", np.zeros(0, np.int64), np.zeros(0, np.int64)
        pieces = self._parse(data, 0, len(data), closed=True, at_end=True) if data else []
        return self._assemble(data, starts, ends, pieces)

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
        return [Piece(p.start + begin, p.end + begin, p.is_noise, p.crc_ok, p.flags) for p in parse.pieces]

    def _assemble(self, data: bytes, starts: Int64Array, ends: Int64Array, pieces: list[Piece]) -> FrameBatch:
        count = len(pieces)
        first = np.fromiter((p.start for p in pieces), np.int64, count)
        last = np.fromiter((p.end for p in pieces), np.int64, count)
        is_noise = np.fromiter((p.is_noise for p in pieces), np.bool_, count)
        flags = np.fromiter((p.flags for p in pieces), np.uint16, count)
        t_start = starts[first] if count else np.zeros(0, np.int64)
        t_end = ends[last - 1] if count else np.zeros(0, np.int64)
        idle = np.empty(count, np.int64)
        if count:
            idle[1:] = t_start[1:] - t_end[:-1]
            idle[0] = NO_IDLE if self._last_end_ns is None else t_start[0] - self._last_end_ns
            self._last_end_ns = int(t_end[-1])
        if self.timing is TimingQuality.EXACT:
            flags |= self._timing_flags(starts, ends, first, last, idle, is_noise)
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
            crc_ok=np.fromiter((p.crc_ok for p in pieces), np.bool_, count),
            flags=flags,
            is_noise=is_noise,
            idle_before_ns=idle,
        )
        self._next_index += count
        return batch

    def _timing_flags(
        self,
        starts: Int64Array,
        ends: Int64Array,
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
