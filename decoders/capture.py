"""The raw capture model: timestamped chunks of bytes and what is known about them.

A :class:`Chunk` is bytes that arrived together, stamped with the moment its last
byte was completely received. Large captures travel as :class:`ChunkBatch`, the same
information in columns, so that readers and the framer work on numpy arrays rather
than on one Python object per serial read.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum, IntFlag

import numpy as np
import numpy.typing as npt

from decoders.line import LineSettings

Int64Array = npt.NDArray[np.int64]


class TimingQuality(Enum):
    """How far a capture's times can be trusted (see docs/capture-text-format.md)."""

    #: Each time is accurate to well under one bit; bytes of one chunk were contiguous.
    EXACT = "exact"
    #: Times were taken by a host when a read returned; bytes arrived in bursts.
    HOST = "host"


class UartError(IntFlag):
    """What the receiver found wrong with one character (a logic analyzer sees it; a serial
    driver may mark it). The character's byte is kept as it was read."""

    NONE = 0
    #: The stop bit was low at its middle: a glitch, a break, or the wrong baud rate.
    FRAMING = 1
    #: The parity bit does not match the data bits.
    PARITY = 2


UART_ERROR_NAMES = {UartError.FRAMING: "framing", UartError.PARITY: "parity"}
#: Every kind a byte can carry, by its name in text formats and JSONL ("framing+parity").
UART_ERROR_KINDS = {"framing": 1, "parity": 2, "framing+parity": 3}


def uart_error_name(kind: int) -> str:
    """``framing``, ``parity`` or ``framing+parity``."""
    return "+".join(name for flag, name in UART_ERROR_NAMES.items() if kind & flag)


#: The latest time a chunk can have: times are 64-bit nanoseconds since the epoch (the year 2262).
MAX_TIME_NS = 2**63 - 1
#: Byte positions (within a chunk, a frame...) with a UART error, and its kind.
UartErrorMarks = tuple[tuple[int, int], ...]
UInt8Array = npt.NDArray[np.uint8]


@dataclass(frozen=True, slots=True)
class Chunk:
    """Bytes that arrived together; ``t_end_ns`` is when the last one was complete.
    ``uart_errors``: (position in ``data``, :class:`UartError` kind) of characters the
    receiver found wrong; ``channel``: the line they came from (:attr:`CaptureInfo.channels`)."""

    t_end_ns: int
    data: bytes
    uart_errors: UartErrorMarks = ()
    #: Which of the capture's ``channels`` the bytes came from (1-based); 0: not said.
    channel: int = 0


@dataclass(frozen=True, slots=True)
class CaptureInfo:
    """What a capture says about itself, apart from its bytes."""

    line: LineSettings | None
    timing: TimingQuality
    notes: tuple[str, ...] = ()
    #: The names of the lines a capture's chunks came from (``("RX", "TX")``: a logic analyzer's
    #: probes; ``("inbound", "outbound")``: pcapng directions); a chunk's ``channel`` k >= 1 is
    #: ``channels[k - 1]``, 0 that the capture does not say. Empty: one line, nothing said.
    channels: tuple[str, ...] = ()
    #: The index its first frame had where it was cut from (``cut``): its frames are numbered from
    #: it, so that a ticket's "#25" is #25 in the attachment too.
    first_index: int = 0


#: The beginning of a capture's note that says its line settings were found, not given (``capture
#: --line auto``, a logic analyzer's samples): the report says them as guessed.
GUESSED_LINE = "line settings guessed: "


def guessed_line(notes: tuple[str, ...]) -> str | None:
    """How the line settings were guessed, where a note says so."""
    return next((note.removeprefix(GUESSED_LINE) for note in notes if note.startswith(GUESSED_LINE)), None)


@dataclass(frozen=True, slots=True)
class ChunkBatch:
    """Consecutive chunks in columns.

    ``ends[k]`` is the offset one past chunk *k*'s last byte in ``data``; chunk *k*
    is ``data[ends[k-1]:ends[k]]`` (with ``ends[-1]`` taken as 0).
    """

    data: bytes
    ends: Int64Array
    t_end_ns: Int64Array = field(repr=False)
    #: The :class:`UartError` kind of every byte of ``data``; ``None`` when no byte has one
    #: (the common case costs nothing).
    uart_errors: UInt8Array | None = field(default=None, repr=False)
    #: The channel (:attr:`Chunk.channel`) of every chunk; ``None`` when the capture says none.
    channels: UInt8Array | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.ends.shape != self.t_end_ns.shape:
            raise ValueError("ends and t_end_ns must have the same length")
        if len(self.ends) and int(self.ends[-1]) != len(self.data):
            raise ValueError("the last chunk end must equal the data length")
        if self.uart_errors is not None and len(self.uart_errors) != len(self.data):
            raise ValueError("uart_errors must have one entry per byte")
        if self.channels is not None and len(self.channels) != len(self.ends):
            raise ValueError("channels must have one entry per chunk")

    def __len__(self) -> int:
        return len(self.ends)

    @property
    def starts(self) -> Int64Array:
        """Offset of each chunk's first byte in ``data``."""
        starts = np.empty_like(self.ends)
        if len(starts):
            starts[0] = 0
            starts[1:] = self.ends[:-1]
        return starts

    def error_kinds(self) -> UInt8Array:
        """:attr:`uart_errors`, zeros when there are none."""
        return self.uart_errors if self.uart_errors is not None else np.zeros(len(self.data), np.uint8)

    def byte_channels(self) -> UInt8Array | None:
        """:attr:`channels` per byte (each chunk's for its bytes), or ``None``."""
        if self.channels is None:
            return None
        return np.repeat(self.channels, np.diff(self.ends, prepend=0))

    def chunks(self) -> Iterator[Chunk]:
        """The batch as individual chunks."""
        start = 0
        kinds = self.uart_errors
        channels = self.channels.tolist() if self.channels is not None else [0] * len(self)
        for end, t_end, channel in zip(self.ends.tolist(), self.t_end_ns.tolist(), channels, strict=True):
            marks = _marks(kinds[start:end]) if kinds is not None else ()
            yield Chunk(t_end, self.data[start:end], marks, channel)
            start = end

    def slice(self, start: int, stop: int) -> ChunkBatch:
        """Chunks ``start..stop-1`` (positions within the batch)."""
        if start == 0 and stop >= len(self):
            return self
        stop = min(stop, len(self))
        first = int(self.ends[start - 1]) if start else 0
        last = int(self.ends[stop - 1]) if stop > start else first
        kinds, channels = self.uart_errors, self.channels
        return ChunkBatch(self.data[first:last], self.ends[start:stop] - first, self.t_end_ns[start:stop],
                          _none_if_clean(kinds[first:last]) if kinds is not None else None,
                          channels[start:stop] if channels is not None else None)

    @classmethod
    def from_chunks(cls, chunks: Sequence[Chunk]) -> ChunkBatch:
        lengths = np.fromiter((len(c.data) for c in chunks), dtype=np.int64, count=len(chunks))
        times = np.fromiter((c.t_end_ns for c in chunks), dtype=np.int64, count=len(chunks))
        ends = np.cumsum(lengths)
        kinds = None
        if any(c.uart_errors for c in chunks):
            kinds = np.zeros(int(ends[-1]), np.uint8)
            for chunk, end in zip(chunks, ends.tolist(), strict=True):
                for position, kind in chunk.uart_errors:
                    kinds[end - len(chunk.data) + position] |= kind
        channels = None
        if any(c.channel for c in chunks):
            channels = np.fromiter((c.channel for c in chunks), np.uint8, len(chunks))
        return cls(b"".join(c.data for c in chunks), ends, times, kinds, channels)

    @classmethod
    def concat(cls, batches: Sequence[ChunkBatch]) -> ChunkBatch:
        """Consecutive batches as one."""
        if len(batches) == 1:
            return batches[0]
        if not batches:
            return cls.empty()
        bases = np.cumsum([0] + [len(b.data) for b in batches[:-1]])
        ends = np.concatenate([b.ends + base for b, base in zip(batches, bases.tolist(), strict=True)])
        kinds = None
        if any(b.uart_errors is not None for b in batches):
            kinds = np.concatenate([b.error_kinds() for b in batches])
        channels = None
        if any(b.channels is not None for b in batches):
            channels = np.concatenate([b.channels if b.channels is not None else np.zeros(len(b), np.uint8)
                                      for b in batches])
        return cls(b"".join(b.data for b in batches), ends, np.concatenate([b.t_end_ns for b in batches]), kinds,
                   channels)

    @classmethod
    def empty(cls) -> ChunkBatch:
        return cls(b"", np.zeros(0, np.int64), np.zeros(0, np.int64))


def joined_batches(batches: Iterable[ChunkBatch], chunks: int, size: int) -> Iterator[ChunkBatch]:
    """``batches`` joined, in order, into batches of at least ``chunks`` chunks or ``size`` bytes
    (the last may hold fewer). An empty batch (a followed recording's quiet) goes through at once,
    after what is held."""
    held: list[ChunkBatch] = []
    count = held_size = 0
    for batch in batches:
        if not len(batch):
            if held:
                yield ChunkBatch.concat(held)
                held, count, held_size = [], 0, 0
            yield batch
            continue
        held.append(batch)
        count += len(batch)
        held_size += len(batch.data)
        if count >= chunks or held_size >= size:
            yield ChunkBatch.concat(held)
            held, count, held_size = [], 0, 0
    if held:
        yield ChunkBatch.concat(held)


def _marks(kinds: UInt8Array) -> UartErrorMarks:
    positions = np.flatnonzero(kinds)
    return tuple(zip(positions.tolist(), kinds[positions].tolist(), strict=True))


def _none_if_clean(kinds: UInt8Array) -> UInt8Array | None:
    return kinds if kinds.any() else None


def uart_error_marks(kinds: UInt8Array | None) -> UartErrorMarks:
    """(position, kind) of every byte with a UART error in a per-byte kinds column."""
    return () if kinds is None else _marks(kinds)

