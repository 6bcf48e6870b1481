"""Wiring of a capture reader to the decoders and to a view; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from contextlib import closing
from dataclasses import dataclass, replace
from functools import partial
from typing import Generic, Protocol

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier, ProfileBook
from decoders.stats import Statistics
from sniffer.decoding_process import ChildDecoding, DecodingStep, Prepare, Prepared, decode_here
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
    prepare: Prepare[Prepared] | None = None,
    prepared: Callable[[Prepared], None] | None = None,
    jobs: int = 1,
) -> Statistics:
    """Decode every batch of ``reader`` into ``view``, streaming; statistics cover all frames
    (when the view wants them).
    ``raw`` gets the chunks as they are read (exports keep them); ``framed`` the framed and
    paired messages in columns, before annotation (exports that need only the frames).
    ``prepare`` works on those too, where they are made; ``prepared`` gets what it made of a
    batch after ``view`` got the batch.
    ``jobs=2``: reading, framing, pairing and ``prepare`` run in a child process
    (:mod:`sniffer.decoding_process`), forked before ``view.start``; the output is the same."""
    if (prepare is None) != (prepared is None):
        raise ValueError("prepare and prepared come together")
    decoder = Decoder(analysis.line, analysis.timing, response_timeout_ns=analysis.response_timeout_ns)
    info = replace(reader.info, timing=analysis.timing)
    run = partial(_run, source=source, info=info, analysis=analysis, view=view, sinks=_Sinks(raw, framed, prepared))
    if jobs == 1:
        return run(decode_here(reader, decoder, prepare))
    with closing(ChildDecoding(reader, decoder, with_chunks=raw is not None, prepare=prepare)) as child:
        return run(child)


@dataclass(frozen=True)
class _Sinks(Generic[Prepared]):
    """Who gets what besides the view."""

    raw: Callable[[ChunkBatch], None] | None
    framed: Callable[[MessageBatch], None] | None
    prepared: Callable[[Prepared], None] | None


def _run(
    steps: Iterable[DecodingStep[Prepared]],
    *,
    source: str,
    info: CaptureInfo,
    analysis: Analysis,
    view: MessageView,
    sinks: _Sinks[Prepared],
) -> Statistics:
    applier = ProfileApplier(analysis.profiles) if analysis.profiles is not None else None
    annotator = Annotator(applier) if view.wants_messages else None
    statistics = Statistics()
    framed_bytes = 0
    view.start(source, info, analysis.line)

    def deliver(step: DecodingStep[Prepared]) -> None:
        nonlocal framed_bytes
        for position, batch in enumerate(step.batches):
            framed_bytes += len(batch.frames.data)
            if view.wants_statistics:
                statistics.add_batch(batch)
            if sinks.framed is not None:
                sinks.framed(batch)
            if annotator is not None:
                annotated = annotator.annotate_batch(batch)
                view.messages(annotated if analysis.keep is None else annotated.select(analysis.keep(batch)))
            if sinks.prepared is not None:
                sinks.prepared(step.prepared[position])

    for step in steps:
        if sinks.raw is not None and step.chunks is not None:
            sinks.raw(step.chunks)
        deliver(step)
    view.finish(statistics)
    if framed_bytes == 0:
        # Scripts must not take an empty recording (a quiet line, a wrong port) for a healthy bus.
        raise RtuSniffError(ErrorKind.NO_DATA, "the capture holds no bytes, only its header", path=source)
    return statistics
