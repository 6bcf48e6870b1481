"""Wiring of a capture reader to the decoders and to a view; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.message import Message
from decoders.pipeline import Decoder
from decoders.stats import Statistics
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader


class MessageView(Protocol):
    """A sink for decoded messages."""

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None: ...

    def messages(self, messages: list[Message]) -> None: ...

    def finish(self, statistics: Statistics) -> None: ...


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


@dataclass(frozen=True)
class Analysis:
    """How to decode: line, timing, response timeout, and which messages the view gets."""

    line: LineSettings
    timing: TimingQuality
    response_timeout_ns: int | None = None
    keep: Callable[[Message], bool] | None = None
    annotate: bool = True


def analyze(reader: CaptureReader, source: str, analysis: Analysis, view: MessageView) -> Statistics:
    """Decode every batch of ``reader`` into ``view``, streaming; statistics cover all frames."""
    decoder = Decoder(
        analysis.line, analysis.timing, response_timeout_ns=analysis.response_timeout_ns, annotate=analysis.annotate
    )
    statistics = Statistics()
    view.start(source, replace(reader.info, timing=analysis.timing), analysis.line)
    for batch in reader.batches():
        _deliver(decoder.feed(batch), statistics, analysis.keep, view)
    _deliver(decoder.flush(), statistics, analysis.keep, view)
    view.finish(statistics)
    return statistics


def _deliver(
    messages: list[Message], statistics: Statistics, keep: Callable[[Message], bool] | None, view: MessageView
) -> None:
    statistics.add_all(messages)
    view.messages(messages if keep is None else [m for m in messages if keep(m)])
