"""Wiring of a capture reader to the decoders and to the sinks; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from contextlib import closing
from dataclasses import dataclass, replace
from functools import partial
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, TimingQuality
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
    preparing = [sink for sink in sinks if sink.prepare is not None]
    prepare = _each_prepare(preparing) if preparing else None
    run = partial(_run, source=source, info=info, analysis=analysis, sinks=sinks, preparing=preparing)
    if jobs == 1:
        return run(decode_here(reader, decoder, prepare))
    with_chunks = any(sink.wants_chunks for sink in sinks)
    with closing(ChildDecoding(reader, decoder, with_chunks=with_chunks, prepare=prepare)) as child:
        return run(child)


def _each_prepare(preparing: list[Sink]) -> Callable[[MessageBatch], tuple[Any, ...]]:
    """One ``prepare`` that runs every sink's, in order."""
    stages = [sink.prepare for sink in preparing if sink.prepare is not None]
    return lambda batch: tuple(stage(batch) for stage in stages)


def _run(
    steps: Iterable[DecodingStep[tuple[Any, ...]]],
    *,
    source: str,
    info: CaptureInfo,
    analysis: Analysis,
    sinks: Sequence[Sink],
    preparing: list[Sink],
) -> Statistics:
    applier = ProfileApplier(analysis.profiles) if analysis.profiles is not None else None
    chunk_sinks = [sink for sink in sinks if sink.wants_chunks]
    frame_sinks = [sink for sink in sinks if sink.wants_frames]
    message_sinks = [sink for sink in sinks if sink.wants_messages]
    counts = any(sink.wants_statistics for sink in sinks)
    annotator = Annotator(applier) if message_sinks else None
    statistics = Statistics()
    framed_bytes = 0
    for sink in sinks:
        sink.start(source, info, analysis.line)

    def deliver(step: DecodingStep[tuple[Any, ...]]) -> None:
        nonlocal framed_bytes
        for position, batch in enumerate(step.batches):
            framed_bytes += len(batch.frames.data)
            if counts:
                statistics.add_batch(batch)
            for sink in frame_sinks:
                sink.frames(batch)
            if annotator is not None:
                annotated = annotator.annotate_batch(batch)
                kept = annotated if analysis.keep is None else annotated.select(analysis.keep(batch))
                for sink in message_sinks:
                    sink.messages(kept)
            for sink, value in zip(preparing, step.prepared[position] if preparing else (), strict=True):
                sink.prepared(value)

    for step in steps:
        if step.chunks is not None:
            for sink in chunk_sinks:
                sink.chunks(step.chunks)
        deliver(step)
    for sink in sinks:
        sink.finish(statistics)
    if framed_bytes == 0:
        # Scripts must not take an empty recording (a quiet line, a wrong port) for a healthy bus.
        raise RtuSniffError(ErrorKind.NO_DATA, "the capture holds no bytes, only its header", path=source)
    return statistics
