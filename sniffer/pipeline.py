"""Wiring of a capture reader to the decoders and to the sinks; no argparse, no printing."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from contextlib import closing
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameBatch
from decoders.line import LineSettings
from decoders.message import MessageBatch, slice_messages
from decoders.pipeline import Decoder, annotator
from decoders.stats import SkippedReads, Statistics
from sniffer.decoding_process import ChildDecoding, DecodingStep, decode_here
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader
from sniffer.io.following import FollowingReader
from sniffer.selection import EVERYTHING, Selection, Window
from sniffer.sinks import Sink

if TYPE_CHECKING:
    from decoders.pipeline import Annotation
    from decoders.profiles.book import ProfileBook

#: Frames before a window whose requests are decoded for the answers inside it.
OPEN_REQUESTS_BEFORE = 64
#: Chunks read are joined into batches of this many where the sinks take neither messages nor
#: raw chunks (``stats``, ``compare``, ``cut``), and the capture is not followed as it grows:
#: framing and pairing cost a fixed part per batch, and such batches hold little per frame; the
#: outputs that annotate hold a batch's objects and would gain less for much more memory.
#: (0: batches as read.)
COUNTING_BATCH_CHUNKS = 65536
#: ... or of this many bytes, whichever comes first: framing host timing holds a batch's bytes
#: many times over, and a capture of host reads holds few chunks per megabyte, so a batch of
#: exact timing is joined (about 41 000 chunks of 11 bytes) where one of host reads is left as read.
COUNTING_BATCH_BYTES = 400_000
#: Chunks read are joined into batches of this many (or of :data:`COUNTING_BATCH_BYTES`) where
#: every sink that takes messages spends more per batch than per frame and holds a batch only
#: while it writes it (``Sink.joins_batches``: the Parquet dataset), none takes raw chunks, and
#: the capture is not followed. Four times the readers' 8 192: larger batches were no faster and
#: held more; JSONL, which holds its records' texts per batch, runs slower so. The figures that
#: chose these three: ``docs/performance.md`` and the history of this file.
JOINED_BATCH_CHUNKS = 32768


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
    #: Which annotated messages of a batch the message sinks get (all if ``None``).
    keep: Callable[[AnnotatedBatch], npt.NDArray[np.bool_]] | None = None
    profiles: ProfileBook | None = None
    #: The part of the capture to look at, and how many frames to show at most.
    selection: Selection = EVERYTHING


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
    decoder = Decoder(analysis.line, analysis.timing, response_timeout_ns=analysis.response_timeout_ns,
                      first_index=reader.info.first_index)
    info = replace(reader.info, timing=analysis.timing)
    delivery = Delivery(sinks, analysis.profiles, analysis.keep, analysis.selection)
    # With a window or a limit the parent prepares the part it delivers (see Delivery.batch).
    prepare = _each_prepare(delivery.preparing) if delivery.preparing and not delivery.selective else None
    run = partial(_run, source=source, info=info, analysis=analysis, delivery=delivery)
    join = None if isinstance(reader, FollowingReader) else delivery.joined()
    if jobs == 1:
        statistics = run(decode_here(reader, decoder, prepare, join=join))
    else:
        with_chunks = any(sink.wants_chunks for sink in sinks)
        with closing(ChildDecoding(reader, decoder, with_chunks=with_chunks, prepare=prepare, join=join)) as child:
            statistics = run(child)
    missed = delivery.window_missed()
    if missed is not None:
        reader.warnings.append(f"{source}: {missed}")
    return statistics


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
                 keep: Callable[[AnnotatedBatch], npt.NDArray[np.bool_]] | None = None,
                 selection: Selection = EVERYTHING) -> None:
        self.sinks = list(sinks)
        self.preparing = [sink for sink in sinks if sink.prepare is not None]
        self._chunk_sinks = [sink for sink in sinks if sink.wants_chunks]
        self._frame_sinks = [sink for sink in sinks if sink.wants_frames]
        self._message_sinks = [sink for sink in sinks if sink.wants_messages]
        self._counts = any(sink.wants_statistics for sink in sinks)
        self._profiles = profiles
        #: Made at the start (:meth:`start`): with two processes, after the decoding process is
        #: forked, so that it does not wait for the decoders it never runs to be imported.
        self._annotator: Annotation | None = None
        self._keep = keep
        self._window = Window(selection) if selection.windowed else None
        #: Frames the message sinks may still get (``--limit``), ``None``: no limit.
        self._left = selection.limit
        self.statistics = Statistics()
        #: Bytes of every frame and noise record delivered.
        self.framed_bytes = 0
        #: Bytes of every frame read, in the window or not.
        self.read_bytes = 0
        #: Set when nothing more can be delivered (past the window, or the limit reached).
        self.done = False
        self._chunk_span = ChunkSpan()

    def window_missed(self) -> str | None:
        """Where the frames read lie, when the window held none of them (see :meth:`Window.missed`)."""
        return None if self._window is None else self._window.missed()

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        if self._message_sinks:
            self._annotator = annotator(self._profiles)
        for sink in self.sinks:
            sink.start(source, info, line)

    def joined(self) -> tuple[int, int] | None:
        """How many chunks (and bytes) of a capture read whole are joined into a batch: where no
        sink takes raw chunks, :data:`COUNTING_BATCH_CHUNKS` when none takes messages either
        (frames and statistics are all they need), :data:`JOINED_BATCH_CHUNKS` when every one
        that does ``joins_batches``; ``None``: batches as read."""
        if self._chunk_sinks:
            return None
        if not self._message_sinks:
            chunks = COUNTING_BATCH_CHUNKS
        elif all(sink.joins_batches for sink in self._message_sinks):
            chunks = JOINED_BATCH_CHUNKS
        else:
            return None
        return (chunks, COUNTING_BATCH_BYTES) if chunks else None

    @property
    def selective(self) -> bool:
        """Whether only part of the capture is delivered (a window, a limit)."""
        return self._window is not None or self._left is not None

    def chunks(self, chunks: ChunkBatch) -> None:
        """Raw chunks; with a window or a limit, only those whose last byte falls among the frames
        delivered (held back until the frames that hold their bytes are decoded)."""
        if not self._chunk_sinks:
            return
        if not self.selective:
            for sink in self._chunk_sinks:
                sink.chunks(chunks)
            return
        self._chunk_span.add(chunks)

    def release_chunks(self, final: bool = False) -> None:
        for chunks in self._chunk_span.release(final):
            for sink in self._chunk_sinks:
                sink.chunks(chunks)

    def batch(self, batch: MessageBatch, prepared: tuple[Any, ...] = ()) -> None:
        self.read_bytes += len(batch.frames.data)
        if self._window is not None:
            batch = self._windowed(batch)
            self.done = self._window.past
        kept = None
        if self._annotator is not None:
            annotator = self._annotator
            annotated = annotator.annotate_columnar(batch)
            kept = annotated if self._keep is None else annotated.select(self._keep(annotated))
        if self._left is not None:
            batch, kept = self._limited(batch, kept)
        if self.preparing and (self.selective or not prepared):
            # What the decoding process prepared covers whole batches: here, only the part delivered.
            # A live capture prepares here too (one process).
            prepared = tuple(sink.prepare(batch) for sink in self.preparing if sink.prepare is not None)
        self.framed_bytes += len(batch.frames.data)
        if self.selective and len(batch):
            self._chunk_span.delivering(batch.frames)
        if self._counts:
            self.statistics.add_batch(batch)
        for sink in self._frame_sinks:
            sink.frames(batch)
        if kept is not None:
            for sink in self._message_sinks:
                sink.messages(kept)
        for sink, value in zip(self.preparing, prepared, strict=True):
            sink.prepared(value)

    def _windowed(self, batch: MessageBatch) -> MessageBatch:
        """The part of ``batch`` in the window. The requests just before it are decoded too
        (not delivered): the answers inside the window read their addresses from them."""
        assert self._window is not None
        begin, end = self._window.span(batch)
        if begin > 0:
            self._chunk_span.skipped_until(int(batch.frames.t_end_ns[begin - 1]))
        if self._annotator is not None and begin > 0:
            self._annotator.annotate_columnar(slice_messages(batch, max(begin - OPEN_REQUESTS_BEFORE, 0), begin))
        return slice_messages(batch, begin, end)

    def _limited(self, batch: MessageBatch,
                 kept: AnnotatedBatch | None) -> tuple[MessageBatch, AnnotatedBatch | None]:
        """``--limit``: the batch up to the last frame shown once the limit is reached (so that the
        statistics count what was looked at), and the frames shown."""
        assert self._left is not None
        positions = list(range(len(batch))) if kept is None else kept.positions()
        if len(positions) < self._left:
            self._left -= len(positions)
            return batch, kept
        shown = positions[: self._left]
        cut = shown[-1] + 1 if shown else 0
        self._left, self.done = 0, True
        batch = slice_messages(batch, 0, cut)
        return batch, None if kept is None else kept.head(cut)

    def gap(self, skipped: SkippedReads) -> None:
        """Reads a live capture skipped (its decoder has restarted after them): counted, and told."""
        self.statistics.skipped_reads += skipped.reads
        self.statistics.skipped_bytes += skipped.size
        for sink in self.sinks:
            sink.gap(skipped)

    def finish(self) -> Statistics:
        self.release_chunks(final=True)
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
            delivery.batch(batch, step.prepared[position] if delivery.preparing and not delivery.selective else ())
            if delivery.done:
                break
        if delivery.selective:
            delivery.release_chunks()
        if delivery.done:
            break
    if delivery.read_bytes == 0:
        # Scripts must not take an empty recording (a quiet line, a wrong port) for a healthy bus;
        # raised before the sinks finish, so that none writes an empty table or summary first.
        raise RtuSniffError(ErrorKind.NO_DATA, "the capture holds no bytes, only its header", path=source)
    return delivery.finish()


class ChunkSpan:
    """Raw chunks held back until it is known whether their bytes are in the part of the
    capture delivered: a chunk goes with the frames when its last byte ends after the last
    frame skipped and no later than the last frame delivered."""

    def __init__(self) -> None:
        self._pending: list[ChunkBatch] = []
        self._skipped_ns: int | None = None
        self._first_ns: int | None = None
        #: End of the last frame delivered.
        self.last_ns: int | None = None

    def add(self, chunks: ChunkBatch) -> None:
        self._pending.append(chunks)

    def skipped_until(self, t_end_ns: int) -> None:
        if self._first_ns is None:
            self._skipped_ns = t_end_ns

    def delivering(self, frames: FrameBatch) -> None:
        if self._first_ns is None:
            self._first_ns = int(frames.t_start_ns[0])
        self.last_ns = int(frames.t_end_ns[-1])

    def release(self, final: bool) -> list[ChunkBatch]:
        """The chunks now known to go, in order; the undecided stay (none at ``final``)."""
        released, pending = [], self._pending
        self._pending = []
        for chunks in pending:
            times = chunks.t_end_ns
            begin = 0 if self._skipped_ns is None else int(np.searchsorted(times, self._skipped_ns, "right"))
            end = begin if self.last_ns is None else max(int(np.searchsorted(times, self.last_ns, "right")), begin)
            if end > begin:
                released.append(chunks.slice(begin, end))
            if end < len(chunks) and not final:
                self._pending.append(chunks.slice(end, len(chunks)))
        return released
