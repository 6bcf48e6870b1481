"""The raw capture model: timestamped chunks of bytes and what is known about them.

A :class:`Chunk` is bytes that arrived together, stamped with the moment its last
byte was completely received. Large captures travel as :class:`ChunkBatch`, the same
information in columns, so that readers and the framer work on numpy arrays rather
than on one Python object per serial read.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from enum import Enum

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


@dataclass(frozen=True, slots=True)
class Chunk:
    """Bytes that arrived together; ``t_end_ns`` is when the last one was complete."""

    t_end_ns: int
    data: bytes


@dataclass(frozen=True, slots=True)
class CaptureInfo:
    """What a capture says about itself, apart from its bytes."""

    line: LineSettings | None
    timing: TimingQuality
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class ChunkBatch:
    """Consecutive chunks in columns.

    ``ends[k]`` is the offset one past chunk *k*'s last byte in ``data``; chunk *k*
    is ``data[ends[k-1]:ends[k]]`` (with ``ends[-1]`` taken as 0).
    """

    data: bytes
    ends: Int64Array
    t_end_ns: Int64Array = field(repr=False)

    def __post_init__(self) -> None:
        if self.ends.shape != self.t_end_ns.shape:
            raise ValueError("ends and t_end_ns must have the same length")
        if len(self.ends) and int(self.ends[-1]) != len(self.data):
            raise ValueError("the last chunk end must equal the data length")

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

    def chunks(self) -> Iterator[Chunk]:
        """The batch as individual chunks."""
        start = 0
        for end, t_end in zip(self.ends.tolist(), self.t_end_ns.tolist(), strict=True):
            yield Chunk(t_end, self.data[start:end])
            start = end

    @classmethod
    def from_chunks(cls, chunks: Sequence[Chunk]) -> ChunkBatch:
        lengths = np.fromiter((len(c.data) for c in chunks), dtype=np.int64, count=len(chunks))
        times = np.fromiter((c.t_end_ns for c in chunks), dtype=np.int64, count=len(chunks))
        return cls(b"".join(c.data for c in chunks), np.cumsum(lengths), times)

    @classmethod
    def empty(cls) -> ChunkBatch:
        return cls(b"", np.zeros(0, np.int64), np.zeros(0, np.int64))


def batch_chunks(chunks: Iterable[Chunk], max_chunks: int = 4096) -> Iterator[ChunkBatch]:
    """Group a stream of chunks into batches of at most ``max_chunks``."""
    pending: list[Chunk] = []
    for chunk in chunks:
        pending.append(chunk)
        if len(pending) >= max_chunks:
            yield ChunkBatch.from_chunks(pending)
            pending = []
    if pending:
        yield ChunkBatch.from_chunks(pending)
