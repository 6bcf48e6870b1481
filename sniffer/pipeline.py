"""Wiring of a capture reader to the decoders and to the sinks; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from contextlib import closing
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier, ProfileBook
from decoders.stats import Statistics
from sniffer.decoding_process import ChildDecoding, DecodingStep, decode_here
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader
from sniffer.sinks import Sink


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
    """How to decode: line, timing, response timeout, and which messages the sinks get."""

    line: LineSettings
    timing: TimingQuality
    response_timeout_ns: int | None = None
    #: Which messages of a batch the message sinks get (all if ``None``).
    keep: Callable[[MessageBatch], npt.NDArray[np.bool_]] | None = None
    profiles: ProfileBook | None = None


def analyze(
    reader: CaptureReader,
    source: str,
    analysis: Analysis,
    sinks: Sequence[Sink],
    *,
    jobs: int = 1,
) -> Statistics:
    """Decode every batch of ``reader`` into ``sinks`` (:mod:`sniffer.sinks`: each gets what it
    wants, in the order of the list), streaming; statistics cover all frames (when a sink wants
    them). ``jobs=2``: reading, framing, pairing and the sinks' ``prepare`` run in a child
    process (:mod:`sniffer.decoding_process`), forked before any sink starts; the output is the same."""
    decoder = Decoder(analysis.line, analysis.timing, response_timeout_ns=analysis.response_timeout_ns)
    info = replace(reader.info, timing=analysis.timing)
    delivery = Delivery(sinks, analysis.profiles, analysis.keep)
    prepare = _each_prepare(delivery.preparing) if delivery.preparing else None
    run = partial(_run, source=source, info=info, analysis=analysis, delivery=delivery)
    if jobs == 1:
        return run(decode_here(reader, decoder, prepare))
    with_chunks = any(sink.wants_chunks for sink in sinks)
    with closing(ChildDecoding(reader, decoder, with_chunks=with_chunks, prepare=prepare)) as child:
        return run(child)


def _each_prepare(preparing: list[Sink]) -> Callable[[MessageBatch], tuple[Any, ...]]:
    """One ``prepare`` that runs every sink's, in order."""
    stages = [sink.prepare for sink in preparing if sink.prepare is not None]
    return lambda batch: tuple(stage(batch) for stage in stages)


class Delivery:
    """Hands decoded batches to sinks, each what it wants, in the order of the list: the
    statistics (counted when a sink wants them), the framed batch, the annotated batch
    (annotated only when a sink wants messages; filtered by ``keep``), what each sink's
    ``prepare`` made of it. One core for offline analysis (:func:`analyze`) and live capture."""

    def __init__(self, sinks: Sequence[Sink], profiles: ProfileBook | None = None,
                 keep: Callable[[MessageBatch], npt.NDArray[np.bool_]] | None = None) -> None:
        self.sinks = list(sinks)
        self.preparing = [sink for sink in sinks if sink.prepare is not None]
        self._chunk_sinks = [sink for sink in sinks if sink.wants_chunks]
        self._frame_sinks = [sink for sink in sinks if sink.wants_frames]
        self._message_sinks = [sink for sink in sinks if sink.wants_messages]
        self._counts = any(sink.wants_statistics for sink in sinks)
        applier = ProfileApplier(profiles) if profiles is not None else None
        self._annotator = Annotator(applier) if self._message_sinks else None
        self._keep = keep
        self.statistics = Statistics()
        #: Bytes of every frame and noise record delivered.
        self.framed_bytes = 0

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        for sink in self.sinks:
            sink.start(source, info, line)

    def chunks(self, chunks: ChunkBatch) -> None:
        for sink in self._chunk_sinks:
            sink.chunks(chunks)

    def batch(self, batch: MessageBatch, prepared: tuple[Any, ...] = ()) -> None:
        self.framed_bytes += len(batch.frames.data)
        if self._counts:
            self.statistics.add_batch(batch)
        for sink in self._frame_sinks:
            sink.frames(batch)
        if self._annotator is not None:
            annotated = self._annotator.annotate_batch(batch)
            kept = annotated if self._keep is None else annotated.select(self._keep(batch))
            for sink in self._message_sinks:
                sink.messages(kept)
        for sink, value in zip(self.preparing, prepared, strict=True):
            sink.prepared(value)

    def finish(self) -> Statistics:
        for sink in self.sinks:
            sink.finish(self.statistics)
        return self.statistics


def _run(
    steps: Iterable[DecodingStep[tuple[Any, ...]]],
    *,
    source: str,
    info: CaptureInfo,
    analysis: Analysis,
    delivery: Delivery,
) -> Statistics:
    delivery.start(source, info, analysis.line)
    for step in steps:
        if step.chunks is not None:
            delivery.chunks(step.chunks)
        for position, batch in enumerate(step.batches):
            delivery.batch(batch, step.prepared[position] if delivery.preparing else ())
    statistics = delivery.finish()
    if delivery.framed_bytes == 0:
        # Scripts must not take an empty recording (a quiet line, a wrong port) for a healthy bus.
        raise RtuSniffError(ErrorKind.NO_DATA, "the capture holds no bytes, only its header", path=source)
    return statistics
