"""The decoding pipeline without I/O: chunk batches in, message batches out."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from decoders.capture import ChunkBatch, TimingQuality
from decoders.frame import FrameBatch
from decoders.framer import Framer
from decoders.line import LineSettings
from decoders.line_check import LineRateCheck
from decoders.message import NONE, Message, MessageBatch
from decoders.modbus.matcher import Matcher

if TYPE_CHECKING:
    from decoders.decoded_batch import AnnotatedBatch
    from decoders.profiles.book import ProfileBook

#: The most the delivery delay may raise the response timeout to.
DELIVERY_FLOOR_CAP_NS = 3_000_000_000


class Decoder:
    """Frames and pairs a capture; ``feed`` chunk batches in order, then ``flush``.

    Message batches carry roles, pairing and flags in columns, which is all that
    statistics need; :class:`Annotator` turns them into decoded messages.
    """

    def __init__(self, line: LineSettings, timing: TimingQuality, *, response_timeout_ns: int | None = None,
                 host_gap_ns: int | None = None, first_index: int = 0) -> None:
        """``host_gap_ns``: on host timing, the quiet between reads that certainly ends a frame
        (a live capture that knows its port: :class:`~decoders.framer.Framer`); ``first_index``:
        the first frame's index (a cut's: :attr:`~decoders.capture.CaptureInfo.first_index`)."""
        self.framer = Framer(line, timing, host_gap_ns, first_index=first_index)
        self.matcher = Matcher(response_timeout_ns)
        #: Host times are when the PC read the bytes: a request and its answer often come in one
        #: read (0 ms) or an answer a read later (the read timeout). They pair frames and time
        #: requests out, but a latency from them would be a measured-looking number nobody
        #: measured: published latencies are ``NONE`` on host captures ("n/a: host timing").
        self.measures_latency = timing is TimingQuality.EXACT
        self.line_check = LineRateCheck(line, timing)

    def feed(self, batch: ChunkBatch) -> list[MessageBatch]:
        """The messages ``batch`` completes. A chunk without bytes says the line was heard, quiet,
        until its time (a live capture's recording ends with one): it counts as a :meth:`tick`
        then, wherever it stands, so that a recording decodes as the live view did."""
        self.line_check.feed(batch)
        heard = np.flatnonzero(np.diff(batch.ends, prepend=0) == 0).tolist()
        if not heard:
            return [self._decoded(self.framer.feed(batch))]
        decoded, start = [], 0
        for at in heard:
            if at > start:
                decoded.append(self._decoded(self.framer.feed(batch.slice(start, at))))
            decoded += self.tick(int(batch.t_end_ns[at]))
            start = at + 1
        if start < len(batch):
            decoded.append(self._decoded(self.framer.feed(batch.slice(start, len(batch)))))
        return decoded

    def _decoded(self, frames: FrameBatch) -> MessageBatch:
        """``frames`` paired, with the latencies this capture's timing can publish."""
        return self._published(self._matched(frames))

    def _matched(self, frames: FrameBatch) -> MessageBatch:
        if not self.measures_latency:
            # Host reads arrive up to the capture's delivery delay late: no answer is declared
            # missing sooner than twice that (the framer learns it from frames split by reads).
            self.matcher.delivery_floor_ns = min(DELIVERY_FLOOR_CAP_NS, 2 * self.framer.delivery_delay_ns)
        return self.matcher.feed(frames)

    def tick(self, now_ns: int) -> list[MessageBatch]:
        """Live capture: what the passing of time alone completes (idle line, timeouts). Time
        counts for a timeout only up to the bytes the framer still holds: they may be the
        answer, and offline they would have been framed before the next frame judged it."""
        framed = self._decoded(self.framer.close_idle(now_ns))
        held_since = self.framer.held_since_ns()
        heard_ns = now_ns if held_since is None else min(now_ns, held_since)
        return [framed, self._published(self.matcher.tick(heard_ns))]

    def flush(self) -> list[MessageBatch]:
        return [self._decoded(self.framer.flush()), self._published(self.matcher.flush())]

    def _published(self, batch: MessageBatch) -> MessageBatch:
        if self.measures_latency:
            return batch
        return replace(batch, latency_ns=np.full(len(batch), NONE, np.int64))


class Annotation(Protocol):
    """The annotation stage as outputs drive it: paired messages in, the decoded form out
    (:class:`~decoders.decoded_batch.AnnotatedBatch`), batch after batch, in capture order."""

    def annotate_columnar(self, batch: MessageBatch) -> AnnotatedBatch: ...


def annotator(profiles: ProfileBook | None) -> Annotation:
    """The annotation stage (paired messages → :class:`~decoders.decoded_batch.AnnotatedBatch`),
    naming values by ``profiles`` (``None``: naming none). Imported when first asked for: framing
    and pairing alone (``stats``, a decoding process before its fork) need not load it."""
    from decoders.modbus.annotate import Annotator  # noqa: PLC0415 - see above

    return Annotator.naming_by(profiles)


def decode(
    batches: Iterable[ChunkBatch], line: LineSettings, timing: TimingQuality, profiles: ProfileBook | None = None
) -> Iterator[Message]:
    """All decoded messages of a capture, streaming, as every output gets them
    (:meth:`~decoders.modbus.annotate.Annotator.annotate_columnar`); ``profiles`` name the registers."""
    decoder = Decoder(line, timing)
    annotation = annotator(profiles)
    for batch in batches:
        for messages in decoder.feed(batch):
            yield from annotation.annotate_columnar(messages)
    for messages in decoder.flush():
        yield from annotation.annotate_columnar(messages)
