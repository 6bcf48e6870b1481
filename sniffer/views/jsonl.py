"""The ``--format jsonl`` view: one JSON object per line."""

from __future__ import annotations

from typing import Any, TextIO

from decoders.capture import CaptureInfo
from decoders.line import LineSettings
from decoders.message import Message
from decoders.stats import Statistics
from sniffer.views.records import capture_record, device_record, encode_record, frame_record


class JsonlView:
    """Writes a ``capture`` record, then one ``frame`` record per message."""

    def __init__(self, out: TextIO) -> None:
        self._out = out

    wants_messages = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._write(capture_record(source, info, line))

    def messages(self, messages: list[Message]) -> None:
        lines = []
        for message in messages:
            lines.append(encode_record(frame_record(message)))
            if message.device is not None:
                lines.append(encode_record(device_record(message)))
        lines.append(b"")
        self._out.write(b"\n".join(lines).decode())

    def finish(self, statistics: Statistics) -> None:
        """The closing ``summary`` record: statistics of every frame, filtered or not."""
        self._write({"kind": "summary", **statistics.to_dict()})
        self._out.flush()

    def _write(self, record: dict[str, Any]) -> None:
        self._out.write(encode_record(record).decode() + "\n")
