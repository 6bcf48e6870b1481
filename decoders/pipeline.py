"""The decoding pipeline without I/O: chunk batches in, messages out."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from decoders.capture import ChunkBatch, TimingQuality
from decoders.frame import FrameBatch
from decoders.framer import Framer
from decoders.line import LineSettings
from decoders.message import Message
from decoders.modbus.roles import RoleGuesser


class Decoder:
    """Frames and classifies a capture; ``feed`` batches in order, then ``flush``."""

    def __init__(self, line: LineSettings, timing: TimingQuality) -> None:
        self.framer = Framer(line, timing)
        self.roles = RoleGuesser()

    def feed(self, batch: ChunkBatch) -> list[Message]:
        return self._classify(self.framer.feed(batch))

    def flush(self) -> list[Message]:
        return self._classify(self.framer.flush())

    def _classify(self, frames: FrameBatch) -> list[Message]:
        return [self.roles.classify(frame) for frame in frames]


def decode(batches: Iterable[ChunkBatch], line: LineSettings, timing: TimingQuality) -> Iterator[Message]:
    """All messages of a capture, streaming."""
    decoder = Decoder(line, timing)
    for batch in batches:
        yield from decoder.feed(batch)
    yield from decoder.flush()
