"""Wiring of a capture reader to the decoders and to a view; no argparse, no printing."""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.message import Message
from decoders.pipeline import Decoder
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader


class MessageView(Protocol):
    """A sink for decoded messages."""

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None: ...

    def messages(self, messages: list[Message]) -> None: ...

    def finish(self) -> None: ...


def effective_line(info: CaptureInfo, override: LineSettings | None, path: str) -> LineSettings:
    """The line settings to decode with: the override, else the capture's own."""
    if override is not None:
        return override
    if info.line is None:
        raise RtuSniffError(
            ErrorKind.NO_LINE_SETTINGS,
            "the capture does not say its line settings; give them with --line BAUD FORMAT, e.g. --line 19200 8E1",
            path=path,
        )
    return info.line


def analyze(reader: CaptureReader, source: str, line: LineSettings, timing: TimingQuality, view: MessageView) -> None:
    """Decode every batch of ``reader`` into ``view``, streaming."""
    decoder = Decoder(line, timing)
    view.start(source, replace(reader.info, timing=timing), line)
    for batch in reader.batches():
        view.messages(decoder.feed(batch))
    view.messages(decoder.flush())
    view.finish()
