"""Wiring of a capture reader to the decoders and to a view; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier, ProfileBook
from decoders.stats import Statistics
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader


class MessageView(Protocol):
    """A sink for decoded messages; one that does not ``wants_messages`` gets only the statistics,
    one that does not ``wants_statistics`` gets them empty (they cost a fifth of a decoded export)."""

    wants_messages: bool
    wants_statistics: bool

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None: ...

    def messages(self, batch: AnnotatedBatch) -> None: ...

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
    #: Which messages of a batch the view gets (all if ``None``).
    keep: Callable[[MessageBatch], npt.NDArray[np.bool_]] | None = None
    profiles: ProfileBook | None = None


def analyze(
    reader: CaptureReader,
    source: str,
    analysis: Analysis,
    view: MessageView,
    *,
    raw: Callable[[ChunkBatch], None] | None = None,
    framed: Callable[[MessageBatch], None] | None = None,
) -> Statistics:
    """Decode every batch of ``reader`` into ``view``, streaming; statistics cover all frames
    (when the view wants them).
    ``raw`` gets the chunks as they are read (exports keep them); ``framed`` the framed and
    paired messages in columns, before annotation (exports that need only the frames)."""
    decoder = Decoder(analysis.line, analysis.timing, response_timeout_ns=analysis.response_timeout_ns)
    applier = ProfileApplier(analysis.profiles) if analysis.profiles is not None else None
    annotator = Annotator(applier) if view.wants_messages else None
    statistics = Statistics()
    framed_bytes = 0
    view.start(source, replace(reader.info, timing=analysis.timing), analysis.line)

    def deliver(batches: list[MessageBatch]) -> None:
        nonlocal framed_bytes
        for batch in batches:
            framed_bytes += len(batch.frames.data)
            if view.wants_statistics:
                statistics.add_batch(batch)
            if framed is not None:
                framed(batch)
            if annotator is not None:
                annotated = annotator.annotate_batch(batch)
                view.messages(annotated if analysis.keep is None else annotated.select(analysis.keep(batch)))

    for chunks in reader.batches():
        if raw is not None:
            raw(chunks)
        deliver(decoder.feed(chunks))
    deliver(decoder.flush())
    view.finish(statistics)
    if framed_bytes == 0:
        # Scripts must not take an empty recording (a quiet line, a wrong port) for a healthy bus.
        raise RtuSniffError(ErrorKind.NO_DATA, "the capture holds no bytes, only its header", path=source)
    return statistics
