"""The decoding pipeline without I/O: chunk batches in, messages out."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from decoders.capture import ChunkBatch, TimingQuality
from decoders.framer import Framer
from decoders.line import LineSettings
from decoders.message import Message
from decoders.modbus.annotate import Annotator
from decoders.modbus.matcher import Matcher


class Decoder:
    """Frames, pairs and (with ``annotate``) decodes a capture; ``feed`` batches in order, then ``flush``.

    Without ``annotate`` messages carry roles, pairing and flags but no PDU, which is
    all that statistics need.
    """

    def __init__(
        self,
        line: LineSettings,
        timing: TimingQuality,
        *,
        response_timeout_ns: int | None = None,
        annotate: bool = True,
    ) -> None:
        self.framer = Framer(line, timing)
        self.matcher = Matcher(response_timeout_ns)
        self.annotator = Annotator() if annotate else None

    def feed(self, batch: ChunkBatch) -> list[Message]:
        return self._finish(self.matcher.feed(self.framer.feed(batch)))

    def flush(self) -> list[Message]:
        messages = self.matcher.feed(self.framer.flush())
        return self._finish(messages + self.matcher.flush())

    def _finish(self, messages: list[Message]) -> list[Message]:
        if self.annotator is None:
            return messages
        return [self.annotator.annotate(m) for m in messages]


def decode(
    batches: Iterable[ChunkBatch], line: LineSettings, timing: TimingQuality, *, annotate: bool = True
) -> Iterator[Message]:
    """All messages of a capture, streaming."""
    decoder = Decoder(line, timing, annotate=annotate)
    for batch in batches:
        yield from decoder.feed(batch)
    yield from decoder.flush()
