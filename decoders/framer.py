"""The framer: frames from timing where timing can be trusted, from content elsewhere.

Timing cuts the stream into segments at silences that certainly separate frames
(numpy over the silences where chunks meet, :class:`decoders.byte_times.ByteClock`):
t3.5 on an ``exact`` capture; on a ``host`` one, 3 s unless ``host_gap_ns`` says
otherwise: a read may return mid-frame and the rest of the frame come a read timeout
later (pyserial loops wait up to a second or two), so no shorter gap proves anything.
What the capture's read loop really does is learned from the frames themselves
(:mod:`decoders.framing.delivery`), and sets the matcher's least response timeout. A live capture knows
its own reader: :meth:`Framer.close_idle` closes the open segment after 100 ms
of quiet. Segments that are one whole valid frame, two clean frames (an answer
sooner than t3.5) or a clean frame and 1..3 stray bytes (a glitch) are recognised
in bulk (:mod:`decoders.framing.fast`); :func:`decoders.framing.best_parse.parse_segment`
cuts the others into frames and noise by the best parse of their content, with
silences > t1.5 as evidence on exact captures. Every byte ends up in exactly one
frame or noise record.

Flags: ``gap_1_5`` on a silence > t1.5 inside a frame and ``short_idle`` on a frame
whose silence before it was < t3.5, both only where timing is ``exact``;
``truncated`` and ``bad_length`` come from the content pass; ``uart_error`` on a frame with
a character the receiver found wrong (the capture says which: a logic analyzer's decode),
whose framing errors the content pass weighs too (:mod:`decoders.framing.evidence`).
Where the capture says which line bytes came from (a logic analyzer's RX and TX probes,
pcapng directions), bytes of two lines never share a frame: a change of line is a cut.

Timestamps have 1 ns resolution and byte times are rounded to it, so thresholds
are compared with 1 ns of allowance.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.byte_times import ByteClock
from decoders.capture import ChunkBatch, Int64Array, TimingQuality, UartError, UInt8Array
from decoders.crc import crc_ok_many
from decoders.frame import NO_IDLE, FrameBatch, FrameFlag
from decoders.framing.best_parse import Pieces, SegmentParse, parse_segment
from decoders.framing.content import OpenRequest, replayed_open_request
from decoders.framing.delivery import DeliveryDelay
from decoders.framing.fast import (
    clean_whole,
    frame_pair_segments,
    has_own_rule,
    single_frame_segments,
    whole_by_own_rule,
)
from decoders.framing.programme import Context
from decoders.line import LineSettings
from decoders.memo import Memo
from decoders.modbus.layouts import MAX_ADU

#: Rounding allowance when comparing integer-ns silences with fractional thresholds.
TOLERANCE_NS = 1.0
#: On host-timed capture files, the silence that certainly separates frames: longer
#: than any read loop's delivery delay (see the module docstring).
HOST_GAP_NS = 3_000_000_000
#: Per byte: UART error kinds and channels (``None``: the capture says none).
ByteMarks = tuple[UInt8Array | None, UInt8Array | None]
#: A run of bytes' clock, the positions where its chunks begin, and of its bytes after a
#: silence > t1.5 (exact timing; none on host timing).
Timed = tuple[ByteClock, Int64Array, Int64Array]
#: Live capture through rtusniff's own reader: quiet this long means the line is idle
#: (above a USB adapter's 16 ms latency timer and the host's jitter).
LIVE_IDLE_NS = 100_000_000
#: Closed segments up to this long have their parse remembered (:meth:`Framer._parse`), up to
#: ``2 × PARSE_MEMO_SIZE`` of them: a bus repeats its requests, and a request the fast path
#: cannot take whole (one ending in 0x00 that reads as an answer and a glitch too) went through
#: the programme every time, which slowed framing many times over where a few such requests are
#: polled. A parse kept costs about 1 kB (its pieces' arrays): 2 × 512 of them, 1 MB at most.
PARSE_MEMO_LONGEST = 2 * MAX_ADU
PARSE_MEMO_SIZE = 512


class Framer:
    """Splits a byte stream into frames and noise; ``feed`` batches in order, then ``flush``.

    Held back between calls: the open segment's bytes after its last committed piece
    (a few maximum frames; see :mod:`decoders.framing.best_parse`). ``fast=False``
    parses every segment by the plain dynamic programme once it is closed: the
    reference the tests hold the fast path to.
    """

    def __init__(
        self,
        line: LineSettings,
        timing: TimingQuality = TimingQuality.EXACT,
        host_gap_ns: int | None = None,
        *,
        fast: bool = True,
        first_index: int = 0,
    ) -> None:
        """``first_index``: the index of the first frame (a cut's frames keep their numbers)."""
        self.line = line
        self.timing = timing
        self.fast = fast
        host_gap = HOST_GAP_NS if host_gap_ns is None else host_gap_ns
        self._boundary_ns = line.t3_5_ns - TOLERANCE_NS if timing is TimingQuality.EXACT else float(host_gap)
        self._idle_ns = self._boundary_ns if timing is TimingQuality.EXACT else float(min(host_gap, LIVE_IDLE_NS))
        self._delivery = DeliveryDelay()
        self._data = b""
        self._clock = ByteClock.empty(line.char_time_ns)
        #: UART error kinds and channels of the held bytes; ``None`` while the capture has shown none.
        self._kinds: UInt8Array | None = None
        self._channels: UInt8Array | None = None
        self._at_capture_start = True
        #: The held bytes begin where a valid frame committed from their segment ended (the
        #: parse of the rest must know, as the parse of the whole segment would).
        self._follows_frame = False
        self._open_request: OpenRequest = None
        self._next_index = first_index
        self._last_end_ns: int | None = None
        self._parses: Memo[tuple[bytes, Context, OpenRequest], SegmentParse] = Memo(PARSE_MEMO_SIZE)

    @property
    def delivery_delay_ns(self) -> int:
        """Host timing: how late the capture's read loop delivers bytes, as learned so far
        (:mod:`decoders.framing.delivery`); 0 on exact timing."""
        return self._delivery.longest_ns

    def feed(self, batch: ChunkBatch) -> FrameBatch:
        """Frames and noise that ``batch`` completes."""
        clock = self._clock.then(ByteClock.of(batch, self.line.char_time_ns))
        data = self._data + batch.data
        if batch.uart_errors is not None or self._kinds is not None:
            held = self._kinds if self._kinds is not None else np.zeros(len(self._data), np.uint8)
            self._kinds = np.concatenate([held, batch.error_kinds()])
        new_channels = batch.byte_channels()
        if new_channels is not None or self._channels is not None:
            held = self._channels if self._channels is not None else np.zeros(len(self._data), np.uint8)
            fed = new_channels if new_channels is not None else np.zeros(len(batch.data), np.uint8)
            self._channels = np.concatenate([held, fed])
        kinds, channels = self._kinds, self._channels
        silent_at, silences = clock.silences()
        cuts = silent_at[silences >= self._boundary_ns]
        if channels is not None:  # bytes of two lines never share a frame
            cuts = np.union1d(cuts, np.flatnonzero(channels[1:] != channels[:-1]) + 1)
        pauses = self._pauses(silent_at, silences)
        bounds = np.concatenate([np.zeros(1, np.int64), cuts])
        parts = [self._closed_segments(data, pauses, kinds, bounds)]
        open_start = int(bounds[-1])
        kept_from = open_start
        if len(data) > open_start:
            open_pieces = self._parse(data, pauses, open_start, len(data), closed=False, kinds=kinds)
            parts.append(open_pieces)
            kept_from = int(open_pieces.last[-1]) if len(open_pieces) else open_start
            if len(open_pieces):
                self._follows_frame = bool(open_pieces.crc_ok[-1] and not open_pieces.is_noise[-1])
            elif open_start > 0:
                self._follows_frame = False  # the held bytes begin at a timing cut
        self._data, self._clock = data[kept_from:], clock.tail(kept_from)
        self._kinds = None if kinds is None or not kinds[kept_from:].any() else kinds[kept_from:]
        self._channels = None if channels is None else channels[kept_from:]
        return self._assemble(data, (clock, silent_at, pauses), Pieces.join(parts), (kinds, channels))

    def _pauses(self, silent_at: Int64Array, silences: Int64Array) -> Int64Array:
        """Of the bytes after a silence (``silent_at``, :meth:`ByteClock.silences`), those
        after one > t1.5: evidence inside a segment, on exact timing alone."""
        if self.timing is not TimingQuality.EXACT:
            return silent_at[:0]
        pauses: Int64Array = silent_at[silences > self.line.t1_5_ns + TOLERANCE_NS]
        return pauses

    def close_idle(self, now_ns: int) -> FrameBatch:
        """Live capture: the open segment is closed once the line has been quiet for t3.5
        (exact) or ``LIVE_IDLE_NS`` (host), without waiting for a next byte."""
        # The clock has no empty chunk: its last chunk's time is when the last byte ended.
        if not self._data or now_ns - int(self._clock.t_end_ns[-1]) < self._idle_ns:
            return self._assemble(b"", self._timed(ByteClock.empty(self.line.char_time_ns)), Pieces.of([]),
                                  (None, None))
        data, clock, marks = self._take_held()
        timed = self._timed(clock)
        pieces = self._parse(data, timed[2], 0, len(data), closed=True, kinds=marks[0])
        self._follows_frame = False
        return self._assemble(data, timed, pieces, marks)

    def held_since_ns(self) -> int | None:
        """When the earliest byte the framer still holds (not yet in a frame) may have begun on
        the wire, at the earliest: its chunk's end less the chunk's bytes; ``None`` when it holds
        none. Those bytes may be an answer: no request may be timed out at or after this."""
        if not self._data:
            return None
        return int(self._clock.t_end_ns[0]) - int(self._clock.ends[0] * self.line.char_time_ns) - 1

    def flush(self) -> FrameBatch:
        """Everything still held, at the end of the capture."""
        data, clock, marks = self._take_held()
        timed = self._timed(clock)
        pieces = self._parse(data, timed[2], 0, len(data), closed=True, at_end=True, kinds=marks[0]) if data \
            else Pieces.of([])
        self._follows_frame = False
        return self._assemble(data, timed, pieces, marks)

    def _take_held(self) -> tuple[bytes, ByteClock, ByteMarks]:
        held = self._data, self._clock, (self._kinds, self._channels)
        self._data, self._clock = b"", ByteClock.empty(self.line.char_time_ns)
        self._kinds = self._channels = None
        return held

    def _timed(self, clock: ByteClock) -> Timed:
        """``clock`` with where its chunks begin and its pauses (see :data:`Timed`)."""
        silent_at, silences = clock.silences()
        return clock, silent_at, self._pauses(silent_at, silences)

    def _closed_segments(self, data: bytes, pauses: Int64Array, kinds: UInt8Array | None,
                         bounds: Int64Array) -> Pieces:
        """Pieces of the segments ``data[bounds[i]:bounds[i+1]]``: whole frames and pairs of
        pieces in bulk, the rest through the content parser (``pauses``: the bytes after a
        silence > t1.5; ``kinds``: the bytes' UART errors)."""
        seg_starts, seg_ends = bounds[:-1], bounds[1:]
        single, zero_ended = single_frame_segments(data, seg_starts, seg_ends, crc_ok_many(data, bounds))
        if not self.fast:
            single[:] = False
        # Segments only the programme can cut: no pair, no frame and stray bytes.
        to_parse = np.zeros(len(single), np.bool_)
        if self.fast and zero_ended.any():
            ended = np.flatnonzero(zero_ended)
            clean, settled = clean_whole(data, seg_starts[ended], seg_ends[ended])
            single[ended] = clean
            to_parse[ended] = settled & ~clean
        slow = np.flatnonzero(~single & ~to_parse)
        paired = None
        if self.fast and len(slow):
            # Whole frames the vectorised test left out (ending in 0x00, a rule walking the
            # content) are found with the pairs; the pieces of the pairs are known too.
            paired, slow = self._pairs(data, (pauses, kinds), (seg_starts[slow], seg_ends[slow]), slow, single)
        if to_parse.any():  # apart from the slow ones: in order again
            slow = np.sort(np.concatenate([slow, np.flatnonzero(to_parse)]))
        known = Pieces.frames(seg_starts[single], seg_ends[single])
        whole = Pieces.join([known, paired]).in_order() if paired is not None and len(paired) else known
        frames = ~whole.is_noise
        frame_bounds = (whole.first[frames], whole.last[frames])
        frames_before = np.searchsorted(frame_bounds[0], seg_starts[slow]).tolist()
        parsed: list[Pieces] = []
        done = 0
        for index, upto in zip(slow.tolist(), frames_before, strict=True):
            if index > 0:
                self._at_capture_start = False  # whole frames came before it
            self._open_request = replayed_open_request(data, frame_bounds, range(done, upto), self._open_request)
            parsed.append(self._parse(data, pauses, int(seg_starts[index]), int(seg_ends[index]), closed=True,
                                      kinds=kinds))
            done = upto
        self._open_request = replayed_open_request(data, frame_bounds, range(done, len(frame_bounds[0])),
                                                   self._open_request)
        if len(seg_starts):
            self._at_capture_start = False
        return Pieces.join([whole, *parsed]).in_order() if parsed else whole

    def _pairs(self, data: bytes, marks: tuple[Int64Array, UInt8Array | None], segments: tuple[Int64Array, Int64Array],
               which: Int64Array, single: npt.NDArray[np.bool_]) -> tuple[Pieces, Int64Array]:
        """Of the segments ``which`` (their bounds: ``segments``): those that are one whole
        frame marked in ``single``; the pieces of those that are two frames or a frame and a few
        stray bytes; and the indexes of the others (``marks``: the bytes after a pause, the
        bytes' UART errors)."""
        seg_starts, seg_ends = segments
        pauses, kinds = marks
        pause_at = None
        if self.timing is TimingQuality.EXACT:
            pause_at = np.zeros(len(data), np.bool_)
            pause_at[pauses] = True
        error_at = None if kinds is None else (kinds & UartError.FRAMING) != 0
        first_length, second_frame, whole = frame_pair_segments(data, seg_starts, seg_ends, pause_at, error_at)
        for index in np.flatnonzero(~whole & has_own_rule(data, seg_starts)).tolist():
            whole[index] = whole_by_own_rule(data[int(seg_starts[index]) : int(seg_ends[index])])
        single[which[whole]] = True
        seg_starts, seg_ends, which = seg_starts[~whole], seg_ends[~whole], which[~whole]
        first_length, second_frame = first_length[~whole], second_frame[~whole]
        known = first_length > 0
        split = seg_starts[known] + first_length[known]
        first = np.concatenate([seg_starts[known], split])
        last = np.concatenate([split, seg_ends[known]])
        pieces = Pieces.frames(first, last)
        stray = np.concatenate([np.zeros(len(split), np.bool_), ~second_frame[known]])
        pieces.is_noise[stray] = True
        pieces.crc_ok[stray] = False
        return pieces.in_order(), which[~known]

    def _parse(
        self, data: bytes, pauses: Int64Array, begin: int, stop: int, *, closed: bool,
        at_end: bool = False, kinds: UInt8Array | None = None,
    ) -> Pieces:
        """``pauses``: positions in ``data`` of the bytes after a silence > t1.5 (sorted)."""
        inside = pauses[np.searchsorted(pauses, begin, side="right") : np.searchsorted(pauses, stop)]
        pauses_in = tuple((inside - begin).tolist())
        framing_errors: tuple[int, ...] = ()
        if kinds is not None:
            framing_errors = tuple(np.flatnonzero(kinds[begin:stop] & UartError.FRAMING).tolist())
        context = Context(pauses_in, closed=closed, at_capture_start=self._at_capture_start, at_capture_end=at_end,
                          follows_frame=self._follows_frame and begin == 0,
                          timed=closed, framing_errors=framing_errors)
        parse = self._parse_of(data[begin:stop], context)
        if len(parse.pieces):
            self._at_capture_start = False
            self._open_request = parse.open_request
        return parse.pieces.shifted(begin)

    def _parse_of(self, segment: bytes, context: Context) -> SegmentParse:
        """:func:`parse_segment` of ``segment`` after the open request; on the fast path a closed
        segment's parse, which depends on nothing else, is remembered (its pieces are shared:
        nobody changes them)."""
        if not self.fast or not context.closed or len(segment) > PARSE_MEMO_LONGEST:
            return parse_segment(segment, context, self._open_request, fast=self.fast)
        key = (segment, context, self._open_request)
        parse = self._parses.get(key)
        if parse is None:
            parse = parse_segment(segment, context, self._open_request, fast=self.fast)
            self._parses.put(key, parse)
        return parse

    def _assemble(self, data: bytes, timed: Timed, pieces: Pieces, marks: ByteMarks) -> FrameBatch:
        """``timed``: the clock of ``data``'s bytes, where its chunks begin and its pauses
        (:meth:`_timed`); ``marks``: the UART error kinds and the channels of its bytes (or ``None``)."""
        clock, chunk_starts, pauses = timed
        kinds, channels = marks
        first, last, is_noise, flags = pieces.first, pieces.last, pieces.is_noise, pieces.flags.copy()
        count = len(first)
        # Which bytes begin a piece, up to the last piece's end: mostly a chunk is a frame, and on
        # exact timing a frame follows a pause, so chunks and pauses are told apart by these.
        starts_piece = np.zeros(int(last[-1]) + 1 if count else 0, np.bool_)
        starts_piece[first] = True
        if count:
            t_start, t_end = clock.piece_times(chunk_starts, first, starts_piece)
        else:
            t_start = t_end = np.zeros(0, np.int64)
        if self.timing is TimingQuality.HOST and count:
            # A frame's bytes were back to back on the wire even when two reads delivered them:
            # it ends with its last byte and lasted its length in characters (host times of
            # the first part would stretch it by the read delay).
            whole = ~is_noise
            t_start = np.where(whole, t_end - np.rint((last - first) * self.line.char_time_ns).astype(np.int64),
                               t_start)
        idle = np.empty(count, np.int64)
        if count:
            idle[1:] = t_start[1:] - t_end[:-1]
            idle[0] = NO_IDLE if self._last_end_ns is None else t_start[0] - self._last_end_ns
            self._last_end_ns = int(t_end[-1])
        if self.timing is TimingQuality.EXACT:
            flags |= self._timing_flags(pauses, first=first, last=last, starts_piece=starts_piece, idle=idle,
                                        is_noise=is_noise)
        else:
            self._delivery.learn(data, (clock, *clock.silences()), (first, last), pieces.crc_ok & ~is_noise)
            # Host times are estimates; a negative silence is an artefact of them.
            idle[(idle < 0) & (idle != NO_IDLE)] = 0
        offsets = np.zeros(count + 1, np.int64)
        offsets[1:] = np.cumsum(last - first)
        frame_data = data[int(first[0]) : int(last[-1])] if count else b""
        frame_kinds = None
        if kinds is not None and count:
            frame_kinds = kinds[int(first[0]) : int(last[-1])]
            marked = np.zeros(len(frame_kinds) + 1, np.int64)
            np.cumsum(frame_kinds != 0, out=marked[1:])
            flags |= np.where(marked[offsets[1:]] > marked[offsets[:-1]], FrameFlag.UART_ERROR, 0).astype(np.uint16)
            frame_kinds = frame_kinds if frame_kinds.any() else None
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
            uart_errors=frame_kinds,
            channels=channels[first] if channels is not None and count and channels[first].any() else None,
        )
        self._next_index += count
        return batch

    def _timing_flags(
        self,
        pauses: Int64Array,
        *,
        first: Int64Array,
        last: Int64Array,
        starts_piece: npt.NDArray[np.bool_],
        idle: Int64Array,
        is_noise: npt.NDArray[np.bool_],
    ) -> npt.NDArray[np.uint16]:
        # A frame [first, last) has a silence > t1.5 inside if one of its bytes after the first
        # follows one (pauses are few: each is looked up among the frames).
        has_gap = np.zeros(len(first), np.bool_)
        if len(pauses) and len(first):
            # On exact timing nearly every frame starts after a pause (t3.5 > t1.5): those are
            # told apart by ``starts_piece``, and only the few others looked up.
            pauses = pauses[(pauses > first[0]) & (pauses < last[-1])]
            pauses = pauses[~starts_piece[pauses]]
            holder = np.maximum(np.searchsorted(first, pauses, side="right") - 1, 0)
            has_gap[holder[(pauses > first[holder]) & (pauses < last[holder])]] = True
        short = (idle != NO_IDLE) & (idle < self.line.t3_5_ns - TOLERANCE_NS)
        flags = np.where(has_gap & ~is_noise, FrameFlag.GAP_1_5, 0)
        flags |= np.where(short & ~is_noise, FrameFlag.SHORT_IDLE, 0)
        return flags.astype(np.uint16)
