"""The one interface every output implements: a :class:`Sink` gets what it asks for.

A sink is a set of hooks with no-op defaults (as python-can's ``Listener``): the
pipeline (:func:`sniffer.pipeline.analyze`) calls, for each sink and in the order
of the list it was given,

* ``start`` once, with the source, the capture's info and the line decoded with;
* ``chunks`` with the raw chunks as they are read (``wants_chunks``);
* per decoded batch: ``frames`` with the framed and paired messages in columns,
  before annotation (``wants_frames``), then ``messages`` with the annotated
  batch (``wants_messages``: only then does the pipeline annotate; every sink gets the same
  :class:`~decoders.decoded_batch.AnnotatedBatch`), then
  ``prepared`` with what the sink's ``prepare`` made of that batch;
* ``gap`` where a live capture skipped reads it could not decode in time;
* ``interrupted`` where Ctrl-C stopped the command before the last batch (an output kept as far
  as it got says so in itself where its format can);
* ``finish`` once, with the statistics of the whole capture (counted only when
  a sink ``wants_statistics``);

batches of a capture read whole are joined into larger ones where no sink wants chunks
and every sink that wants messages ``joins_batches`` (or none wants any);

and the command that made the sinks calls ``close`` on each, whatever happened.
``prepare`` is the optional part that runs where the messages are framed and paired
(in the decoding process with ``--jobs 2``): work that needs no annotation, done
there in parallel.

Adding an output is one module with a ``Sink`` subclass plus one line in the table
of the command that offers it (``OUTPUTS`` in :mod:`sniffer.commands.export`,
``FORMATS`` in :mod:`sniffer.commands.analyze`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, Generic, Protocol, TypeVar

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.stats import SkippedReads, Statistics
from sniffer.errors import ErrorKind, RtuSniffError


class Sink:
    """An output; every hook does nothing unless a subclass says otherwise."""

    wants_chunks = False
    wants_frames = False
    wants_messages = False
    wants_statistics = False
    #: Whether the sink spends more per batch than per frame, and holds a batch only while it
    #: writes it: where every sink that wants messages does, the chunks of a capture read whole
    #: are joined into larger batches (``sniffer.pipeline.JOINED_BATCH_CHUNKS``).
    joins_batches = False
    #: Work on a framed batch, where it is framed (see the module docstring); ``None``: none.
    prepare: Callable[[MessageBatch], Any] | None = None

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        """Before the first batch."""

    def chunks(self, batch: ChunkBatch) -> None:
        """Raw chunks as they are read."""

    def frames(self, batch: MessageBatch) -> None:
        """A framed and paired batch, before annotation."""

    def messages(self, batch: AnnotatedBatch) -> None:
        """An annotated batch (what a filter kept of it)."""

    def prepared(self, value: Any) -> None:
        """What ``prepare`` made of the batch just delivered."""

    def gap(self, skipped: SkippedReads) -> None:
        """A live capture's decoding fell behind and skipped reads here (the recording has them);
        decoding starts again after them, as at the start of a capture."""

    def finish(self, statistics: Statistics) -> None:
        """After the last batch."""

    def interrupted(self) -> None:
        """The command was interrupted (Ctrl-C) before the last batch; ``close`` follows. An
        output kept as far as it got says so in itself where its format can."""

    def close(self) -> None:
        """Release what the sink holds; called once, after ``finish`` or after a failure."""


class Closable(Protocol):
    def close(self) -> None: ...


Exporter = TypeVar("Exporter", bound=Closable)


class FileSink(Sink, Generic[Exporter]):
    """A sink writing one file (``-``: standard output) through an exporter: its write
    failures are one error naming the file (exit 11), never a traceback."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        #: Frames written (each output gets every frame).
        self.frames_written = 0
        #: What writes the file, once opened.
        self.exporter: Exporter | None = None

    def close(self) -> None:
        exporter, self.exporter = self.exporter, None
        if exporter is not None:
            with self.writing():
                exporter.close()

    @contextmanager
    def writing(self) -> Iterator[None]:
        """Write failures (a missing folder, a full disk) as one error naming the file."""
        try:
            yield
        except (OSError, RuntimeError) as exc:  # RuntimeError: how Rerun's SDK reports I/O errors
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {reason}",
                                path=self.path or "the viewer") from None
