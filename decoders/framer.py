"""The timing framer: frame boundaries from silences on the wire.

A new frame starts after a silence of at least t3.5; a silence longer than t1.5
inside a frame sets ``gap_1_5`` (the frame is still reported whole and CRC-checked).
The timing pass is numpy over byte times; only the per-frame assembly is Python.

Timestamps have 1 ns resolution and byte times are rounded to it, so a silence is
known to within ±1 ns; the comparisons give that nanosecond to "at the threshold".
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.byte_times import byte_times
from decoders.capture import ChunkBatch, Int64Array
from decoders.crc import crc_ok_many
from decoders.frame import FrameBatch, FrameFlag
from decoders.line import LineSettings

#: Rounding allowance when comparing integer-ns silences with fractional thresholds.
TOLERANCE_NS = 1.0


class TimingFramer:
    """Splits an exact-timed byte stream into frames; ``feed`` batches, then ``flush``.

    The last frame of each batch may continue in the next one, so it is held back
    until a later byte shows the silence that ends it, or until :meth:`flush`.
    Memory is the open frame only.
    """

    def __init__(self, line: LineSettings) -> None:
        self.line = line
        self._pending_data = b""
        self._pending_starts: Int64Array = np.zeros(0, np.int64)
        self._pending_ends: Int64Array = np.zeros(0, np.int64)
        self._next_index = 0
        self._last_frame_end_ns: int | None = None

    def feed(self, batch: ChunkBatch) -> FrameBatch:
        """Frames completed by ``batch``."""
        new_starts, new_ends = byte_times(batch, self.line.char_time_ns)
        data = self._pending_data + batch.data
        starts = np.concatenate([self._pending_starts, new_starts])
        ends = np.concatenate([self._pending_ends, new_ends])
        # silence[i] is the silence before byte i + 1.
        silence = starts[1:] - ends[:-1]
        frame_starts = np.flatnonzero(silence >= self.line.t3_5_ns - TOLERANCE_NS) + 1
        gaps = np.flatnonzero(
            (silence > self.line.t1_5_ns + TOLERANCE_NS) & (silence < self.line.t3_5_ns - TOLERANCE_NS)
        ) + 1
        closed_until = int(frame_starts[-1]) if len(frame_starts) else 0
        self._pending_data = data[closed_until:]
        self._pending_starts = starts[closed_until:]
        self._pending_ends = ends[closed_until:]
        bounds = np.concatenate([[0], frame_starts]).astype(np.int64)
        return self._assemble(
            data[:closed_until], starts[:closed_until], ends[:closed_until], bounds, gaps[gaps < closed_until]
        )

    def flush(self) -> FrameBatch:
        """Emit the open frame at the end of the capture."""
        data, starts, ends = self._pending_data, self._pending_starts, self._pending_ends
        self._pending_data = b""
        self._pending_starts, self._pending_ends = np.zeros(0, np.int64), np.zeros(0, np.int64)
        bounds = np.array([0, len(data)] if data else [0], np.int64)
        gaps = np.flatnonzero(starts[1:] - ends[:-1] > self.line.t1_5_ns + TOLERANCE_NS) + 1
        return self._assemble(data, starts, ends, bounds, gaps)

    def _assemble(
        self,
        data: bytes,
        byte_starts: Int64Array,
        byte_ends: Int64Array,
        bounds: Int64Array,
        gap_positions: npt.NDArray[np.intp],
    ) -> FrameBatch:
        """Frames ``data[bounds[i]:bounds[i+1]]``; ``bounds`` starts at 0 and ends at len(data)."""
        offsets = bounds if len(data) == 0 or bounds[-1] == len(data) else np.append(bounds, len(data))
        count = len(offsets) - 1
        t_end = byte_ends[offsets[1:] - 1] if count else np.zeros(0, np.int64)
        t_start = byte_starts[offsets[:-1]] if count else np.zeros(0, np.int64)
        flags = np.zeros(count, np.uint16)
        if len(gap_positions):
            frame_of_gap = np.searchsorted(offsets, gap_positions, side="right") - 1
            flags[frame_of_gap] |= np.uint16(FrameFlag.GAP_1_5)
        idle = np.empty(count, np.int64)
        if count:
            idle[1:] = t_start[1:] - t_end[:-1]
            idle[0] = -1 if self._last_frame_end_ns is None else t_start[0] - self._last_frame_end_ns
            self._last_frame_end_ns = int(t_end[-1])
        batch = FrameBatch(
            first_index=self._next_index,
            data=data,
            offsets=offsets.astype(np.int64),
            t_start_ns=t_start.astype(np.int64),
            t_end_ns=t_end.astype(np.int64),
            crc_ok=crc_ok_many(data, offsets),
            flags=flags,
            is_noise=np.zeros(count, np.bool_),
            idle_before_ns=idle,
        )
        self._next_index += count
        return batch
