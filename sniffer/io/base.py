"""The interfaces every capture format implements."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from decoders.capture import CaptureInfo, ChunkBatch


class CaptureReader(Protocol):
    """Reads a capture: ``info`` is known once it is open; ``batches`` streams the bytes."""

    info: CaptureInfo
    #: Notes found after the header; complete once ``batches`` is exhausted.
    late_notes: list[str]
    #: Things to tell the user once reading is done (e.g. a recording cut short).
    warnings: list[str]

    def batches(self) -> Iterator[ChunkBatch]: ...

    def close(self) -> None: ...


class CaptureWriter(Protocol):
    """Writes a capture; ``close`` leaves a complete, valid file."""

    def write_batch(self, batch: ChunkBatch) -> None: ...

    def add_notes(self, notes: list[str]) -> None: ...

    def flush(self) -> None:
        """Make everything written so far durable (on disk)."""

    @property
    def size(self) -> int:
        """Bytes written so far."""
        ...

    def close(self) -> None: ...

    def abandon(self) -> None:
        """Close the file as it is, without closing records (after a failed write)."""


@dataclass(frozen=True)
class CaptureFormat:
    """One capture format, declared by its module as ``FORMAT``."""

    name: str
    suffixes: tuple[str, ...]
    description: str
    #: What a file of this format starts with, to recognise it without its suffix.
    magic: bytes
    open_reader: Callable[[str], CaptureReader]
    open_writer: Callable[[str, CaptureInfo], CaptureWriter]
