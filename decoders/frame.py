"""Frames: the framer's output, one per run of bytes it decided belongs together.

Frames travel in columns (:class:`FrameBatch`) so that statistics and exports can
stay in numpy; :class:`Frame` is the one-at-a-time view for decoders and views.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from enum import IntFlag
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import uart_error_marks

MODBUS = 0
USS = 1
PROTOCOL_NAMES = {MODBUS: "modbus", USS: "uss"}

#: ``idle_before_ns`` of the first frame of a capture, which has no frame before it.
NO_IDLE = int(np.iinfo(np.int64).min)


class FrameFlag(IntFlag):
    """Conditions found on a frame; names are the JSONL flag names."""

    NONE = 0
    #: A silence longer than t1.5 inside the frame.
    GAP_1_5 = 1
    #: The silence before the frame was shorter than t3.5; content decided the boundary.
    SHORT_IDLE = 2
    #: The capture or the frame stops before the frame's expected length.
    TRUNCATED = 4
    #: The frame's length does not fit its function code.
    BAD_LENGTH = 8
    #: On a request: no response came in time.
    TIMEOUT = 16
    #: On a request: repeats the previous unanswered request.
    RETRY = 32
    #: On a response: no open request matches it.
    UNEXPECTED = 64
    #: A character of the frame had a framing or parity error (``Frame.uart_errors`` says which).
    UART_ERROR = 128

    @property
    def names(self) -> list[str]:
        """The set flags' JSONL names, in a fixed order."""
        return list(_NAMES_BY_VALUE[self.value])


_FLAG_ORDER = [f for f in FrameFlag if f is not FrameFlag.NONE]
_FLAG_NAMES = {flag: str(flag.name).lower() for flag in _FLAG_ORDER}
#: Every combination of flags, looked up instead of constructed (enum calls are slow).
_FLAGS_BY_VALUE = [FrameFlag(value) for value in range(1 << len(_FLAG_ORDER))]


_NAMES_BY_VALUE = [
    tuple(_FLAG_NAMES[flag] for flag in _FLAG_ORDER if flag.value & value) for value in range(1 << len(_FLAG_ORDER))
]


def flag_names_of(value: int) -> list[str]:
    """The JSONL names of the flags set in ``value``, in their order."""
    return list(_NAMES_BY_VALUE[value])


def flag_set(value: int) -> FrameFlag:
    """The :class:`FrameFlag` of an integer, without the cost of an enum call."""
    return _FLAGS_BY_VALUE[value]


# Not frozen (treat as immutable): a frozen dataclass sets each field through object.__setattr__,
# 4× slower to build, and the annotator builds one per frame it has not seen before.
@dataclass(slots=True)
class Frame:
    """One frame (or one run of noise bytes) with its wire times.

    ``t_start_ns`` is the start of the first byte's start bit, ``t_end_ns`` the end
    of the last byte's stop bit. ``idle_before_ns`` is the silence since the end of
    the previous frame (``None`` for the first frame of a capture).
    """

    index: int
    t_start_ns: int
    t_end_ns: int
    data: bytes
    crc_ok: bool
    flags: FrameFlag
    is_noise: bool = False
    idle_before_ns: int | None = None
    #: ``MODBUS`` or ``USS``.
    protocol: int = 0
    #: (position in ``data``, :class:`decoders.capture.UartError` kind) of characters the
    #: receiver found wrong.
    uart_errors: tuple[tuple[int, int], ...] = ()
    #: The line the frame came from (:attr:`decoders.capture.CaptureInfo.channels`, 1-based); 0: not said.
    channel: int = 0


@dataclass(frozen=True, slots=True)
class FrameBatch:
    """Consecutive frames in columns; frame *i* is ``data[offsets[i]:offsets[i+1]]``."""

    first_index: int
    data: bytes
    offsets: npt.NDArray[np.int64]
    t_start_ns: npt.NDArray[np.int64]
    t_end_ns: npt.NDArray[np.int64]
    crc_ok: npt.NDArray[np.bool_]
    flags: npt.NDArray[np.uint16]
    is_noise: npt.NDArray[np.bool_]
    #: Silence before each frame; ``NO_IDLE`` where there is no previous frame.
    idle_before_ns: npt.NDArray[np.int64]
    #: ``MODBUS`` or ``USS`` per frame; ``None`` when every frame is Modbus.
    protocol: npt.NDArray[np.uint8] | None = None
    #: The :class:`decoders.capture.UartError` kind of every byte of ``data``; ``None`` when no
    #: byte has one.
    uart_errors: npt.NDArray[np.uint8] | None = None
    #: The channel of every frame (:attr:`Frame.channel`); ``None`` when the capture says none.
    channels: npt.NDArray[np.uint8] | None = None

    def __len__(self) -> int:
        return len(self.t_start_ns)

    def __iter__(self) -> Iterator[Frame]:
        rows = self.rows()
        return (rows[position] for position in range(len(self)))

    def rows(self) -> FrameRows:
        """Frames built on demand by position, from columns read once."""
        return FrameRows(self)

    def protocols(self) -> npt.NDArray[np.uint8]:
        """The protocol of every frame."""
        return self.protocol if self.protocol is not None else np.zeros(len(self), np.uint8)

    def error_kinds(self) -> npt.NDArray[np.uint8]:
        """:attr:`uart_errors`, zeros when there are none."""
        return self.uart_errors if self.uart_errors is not None else np.zeros(len(self.data), np.uint8)


class FrameRows:
    """The frames of a batch by position, each built when asked for (columns are read into
    lists at the first request): for stages that need objects for some frames only."""

    def __init__(self, batch: FrameBatch) -> None:
        self._batch = batch
        self._columns: list[list[Any]] | None = None

    def __getitem__(self, position: int) -> Frame:
        if self._columns is None:
            batch = self._batch
            self._columns = [column.tolist() for column in (batch.offsets, batch.t_start_ns, batch.t_end_ns,
                                                            batch.crc_ok, batch.flags, batch.is_noise,
                                                            batch.idle_before_ns, batch.protocols())]
        offsets, start, end, ok, flags, noise, idle, protocol = self._columns
        kinds, channels = self._batch.uart_errors, self._batch.channels
        marks = () if kinds is None or not flags[position] & FrameFlag.UART_ERROR else \
            uart_error_marks(kinds[offsets[position] : offsets[position + 1]])
        return Frame(
            index=self._batch.first_index + position,
            t_start_ns=start[position],
            t_end_ns=end[position],
            data=self._batch.data[offsets[position] : offsets[position + 1]],
            crc_ok=ok[position],
            flags=_FLAGS_BY_VALUE[flags[position]],
            is_noise=noise[position],
            idle_before_ns=None if idle[position] == NO_IDLE else idle[position],
            protocol=protocol[position],
            uart_errors=marks,
            channel=0 if channels is None else int(channels[position]),
        )


_COLUMNS = ("t_start_ns", "t_end_ns", "crc_ok", "flags", "is_noise", "idle_before_ns")


def slice_frames(batch: FrameBatch, start: int, stop: int) -> FrameBatch:
    """Frames ``start..stop-1`` of ``batch`` (positions within the batch)."""
    begin, end = int(batch.offsets[start]), int(batch.offsets[stop])
    return FrameBatch(
        batch.first_index + start,
        batch.data[begin:end],
        batch.offsets[start : stop + 1] - begin,
        protocol=None if batch.protocol is None else batch.protocol[start:stop],
        uart_errors=None if batch.uart_errors is None else batch.uart_errors[begin:end],
        channels=None if batch.channels is None else batch.channels[start:stop],
        **{name: getattr(batch, name)[start:stop] for name in _COLUMNS},
    )


def concat_frames(batches: list[FrameBatch]) -> FrameBatch:
    """Consecutive batches as one."""
    batches = [b for b in batches if len(b)] or batches[:1]
    if len(batches) == 1:
        return batches[0]
    offsets = [batches[0].offsets]
    base = int(batches[0].offsets[-1])
    for batch in batches[1:]:
        offsets.append(batch.offsets[1:] + base)
        base += int(batch.offsets[-1])
    mixed = any(b.protocol is not None for b in batches)
    marked = any(b.uart_errors is not None for b in batches)
    return FrameBatch(
        batches[0].first_index,
        b"".join(b.data for b in batches),
        np.concatenate(offsets),
        protocol=np.concatenate([b.protocols() for b in batches]) if mixed else None,
        uart_errors=np.concatenate([b.error_kinds() for b in batches]) if marked else None,
        channels=np.concatenate([b.channels if b.channels is not None else np.zeros(len(b), np.uint8)
                                for b in batches]) if any(b.channels is not None for b in batches) else None,
        **{name: np.concatenate([getattr(b, name) for b in batches]) for name in _COLUMNS},
    )


def frames_to_batch(frames: list[Frame]) -> FrameBatch:
    """Frame objects (consecutive indices) as a batch."""
    count = len(frames)
    lengths = np.fromiter((len(f.data) for f in frames), np.int64, count)
    offsets = np.zeros(count + 1, np.int64)
    offsets[1:] = np.cumsum(lengths)
    kinds = None
    if any(f.uart_errors for f in frames):
        kinds = np.zeros(int(offsets[-1]), np.uint8)
        for frame, start in zip(frames, offsets.tolist(), strict=False):
            for position, kind in frame.uart_errors:
                kinds[start + position] = kind
    return FrameBatch(
        frames[0].index if frames else 0,
        b"".join(f.data for f in frames),
        offsets,
        np.fromiter((f.t_start_ns for f in frames), np.int64, count),
        np.fromiter((f.t_end_ns for f in frames), np.int64, count),
        np.fromiter((f.crc_ok for f in frames), np.bool_, count),
        np.fromiter((int(f.flags) for f in frames), np.uint16, count),
        np.fromiter((f.is_noise for f in frames), np.bool_, count),
        np.fromiter((NO_IDLE if f.idle_before_ns is None else f.idle_before_ns for f in frames), np.int64, count),
        protocol=np.fromiter((f.protocol for f in frames), np.uint8, count),
        uart_errors=kinds,
        channels=np.fromiter((f.channel for f in frames), np.uint8, count) if any(f.channel for f in frames) else None,
    )
