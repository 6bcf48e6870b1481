"""The ``--format jsonl`` view: one JSON object per line."""

from __future__ import annotations

from typing import Any, TextIO

from decoders.capture import CaptureInfo
from decoders.line import LineSettings
from decoders.message import Message
from decoders.stats import Statistics
from sniffer.views.records import FrameRecordEncoder, capture_record, device_record, encode_record


class JsonlView:
    """Writes a ``capture`` record, then one ``frame`` record per message."""

    def __init__(self, out: TextIO) -> None:
        self._out = out
        self._frames = FrameRecordEncoder()

    wants_messages = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._write(capture_record(source, info, line))

    def messages(self, messages: list[Message]) -> None:
        lines = []
        encode = self._frames.encode
        for message in messages:
            lines.append(encode(message))
            if message.device is not None:
                lines.append(encode_record(device_record(message)).decode())
        lines.append("")
        self._out.write("\n".join(lines))

    def finish(self, statistics: Statistics) -> None:
        """The closing ``summary`` record: statistics of every frame, filtered or not."""
        self._write({"kind": "summary", **statistics.to_dict()})
        self._out.flush()

    def _write(self, record: dict[str, Any]) -> None:
        self._out.write(encode_record(record).decode() + "\n")
