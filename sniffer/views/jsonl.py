"""The ``--format jsonl`` view: one JSON object per line."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, TextIO

from decoders.capture import CaptureInfo
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, Decoding
from decoders.stats import Statistics
from sniffer.views.records import FrameRecordEncoder, capture_record, device_record, encode_record


class JsonlView:
    """Writes a ``capture`` record, then one ``frame`` record per message."""

    def __init__(self, out: TextIO) -> None:
        self._out = out
        self._frames = FrameRecordEncoder()

    wants_messages = True
    wants_statistics = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._write(capture_record(source, info, line))

    def messages(self, batch: AnnotatedBatch) -> None:
        lines = self._frames.encode_batch(batch)
        first, decodings = batch.messages.frames.first_index, batch.decodings
        if any(decoding.device is not None for decoding in decodings):
            lines = list(_with_devices(lines, batch.positions(), first, decodings))
        lines.append("")
        self._out.write("\n".join(lines))

    def finish(self, statistics: Statistics) -> None:
        """The closing ``summary`` record: statistics of every frame, filtered or not."""
        self._write({"kind": "summary", **statistics.to_dict()})
        self._out.flush()

    def _write(self, record: dict[str, Any]) -> None:
        self._out.write(encode_record(record) + "\n")


def _with_devices(lines: list[str], positions: list[int], first: int, decodings: list[Decoding]) -> Iterator[str]:
    """The frame records, each followed by its ``device`` record (a slave identified itself)."""
    for line, position in zip(lines, positions, strict=True):
        yield line
        device = decodings[position].device
        if device is not None:
            yield encode_record(device_record(first + position, device))
