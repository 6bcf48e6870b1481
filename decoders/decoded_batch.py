"""A decoded batch: framed and paired messages in columns with what each says.

The one form the annotator hands to every output (``Sink.messages``); built low in
``decoders/`` so that every output and every decoder can name it without a cycle.

Which frames of a batch are decoded in columns (:mod:`decoders.modbus.columnar`) and which one
by one depends on the frames alone (their function, shape and profile), never on the outputs:
every output gets the same batch. Writers of columns spell the frames in columns from
``columnar``; every other reader takes each frame's :class:`~decoders.message.Decoding`, which
for a frame in columns is built when first asked for (:func:`columnar_decodings`).

This module is the outputs' one way into the decoded form: what a writer of columns reads of
them (:class:`ColumnarFrames`, its params and names, its summary lines, which frames read
alike) is named here, and ``sniffer/`` imports nothing else of :mod:`decoders.modbus` but
the codec registry (:mod:`decoders.modbus.codecs`; an import-linter contract holds it).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from decoders.message import IN_COLUMNS, ROLE_ORDER, Decoding, Message, MessageBatch, ParamValue, slice_messages
from decoders.modbus.alike import alike, mostly_distinct
from decoders.modbus.codecs import parse_as
from decoders.modbus.columnar import ColumnarFrames, ColumnarNames, ColumnarParams
from decoders.modbus.columnar_text import READ_ANSWER, summaries
from decoders.modbus.param_runs import named_registers
from decoders.modbus.pdu import ReadRequest

#: What writers of columns read (see the module's docstring).
__all__ = ["AnnotatedBatch", "ColumnarFrames", "ColumnarNames", "ColumnarParams", "alike", "columnar_decodings",
           "mostly_distinct", "summaries"]


@dataclass(frozen=True, slots=True)
class AnnotatedBatch:
    """Decoded messages in columns: a :class:`MessageBatch` and each message's decoding.

    ``rows``: the positions kept (by a filter, a limit), ``None`` for all. ``columnar``: the
    kept frames decoded in columns (:meth:`Annotator.annotate_columnar`), whose entries of
    ``decoded`` are :data:`IN_COLUMNS`; :attr:`decodings` has them all, those built when first
    read. Iterating yields the kept messages as objects.
    """

    messages: MessageBatch
    #: Each message's decoding as the annotator made it (:data:`IN_COLUMNS`: in ``columnar``).
    decoded: list[Decoding]
    rows: npt.NDArray[np.int64] | None = None
    columnar: ColumnarFrames | None = None
    #: :attr:`decodings` once built: a one-entry cache in a frozen batch, so that the sinks that
    #: read objects (values, the report, Rerun) build them once between them.
    _built: list[list[Decoding]] = field(default_factory=list, compare=False, repr=False)

    def __len__(self) -> int:
        return len(self.decoded) if self.rows is None else len(self.rows)

    def __iter__(self) -> Iterator[Message]:
        messages, decodings = self.messages.rows(), self.decodings
        for position in self.positions():
            message = messages[position]
            message.decoding = decodings[position]  # fresh from the batch: set rather than copied
            yield message

    @property
    def decodings(self) -> list[Decoding]:
        """Every message's decoding, by position; those of frames in columns built on first read."""
        if self.columnar is None or not len(self.columnar):
            return self.decoded
        if not self._built:
            decodings = list(self.decoded)
            for position, decoding in zip(self.columnar.positions.tolist(),
                                          columnar_decodings(self.columnar, self.messages), strict=True):
                decodings[position] = decoding
            self._built.append(decodings)
        return self._built[0]

    def decoding_at(self, position: int) -> Decoding:
        """The decoding at ``position``; of a frame in columns, the batch's decodings are built
        (for readers that want a few frames' objects among those decoded one by one)."""
        decoding = self.decoded[position]
        return self.decodings[position] if decoding is IN_COLUMNS else decoding

    def positions(self) -> list[int]:
        """The kept positions, in order."""
        return list(range(len(self.decoded))) if self.rows is None else self.rows.tolist()

    def decoded_positions(self) -> list[int]:
        """The kept positions of the messages decoded one by one (not in ``columnar``)."""
        if self.columnar is None or not len(self.columnar):
            return self.positions()
        rest = np.ones(len(self.decoded), np.bool_)
        rest[self.columnar.positions] = False
        if self.rows is not None:
            rest &= _mask(self.rows, len(self.decoded))
        return np.flatnonzero(rest).tolist()

    def decodings_at(self, positions: list[int]) -> list[Decoding]:
        """The decodings at ``positions`` (ordered and distinct, as :meth:`positions` gives them:
        all of them when as many)."""
        decodings = self.decodings
        if len(positions) == len(decodings):
            return decodings
        return list(map(decodings.__getitem__, positions))

    def decoded_at(self, positions: list[int]) -> list[Decoding]:
        """The annotator's decodings at ``positions`` (of :meth:`decoded_positions`: none in columns)."""
        if len(positions) == len(self.decoded):
            return self.decoded
        return list(map(self.decoded.__getitem__, positions))

    def select(self, keep: npt.NDArray[np.bool_]) -> AnnotatedBatch:
        """Only the messages where ``keep`` (one flag per message of ``messages``) is true."""
        if self.rows is not None:
            keep = keep & _mask(self.rows, len(keep))
        rows = np.flatnonzero(keep).astype(np.int64)
        columnar = self.columnar
        if columnar is not None:
            columnar = columnar.take(np.flatnonzero(keep[columnar.positions]))
        return AnnotatedBatch(self.messages, self.decoded, rows, columnar)

    def head(self, stop: int) -> AnnotatedBatch:
        """The messages before position ``stop``, as a batch of those messages alone."""
        rows = None if self.rows is None else self.rows[self.rows < stop]
        columnar = self.columnar
        if columnar is not None:
            columnar = columnar.take(np.flatnonzero(columnar.positions < stop))
        return AnnotatedBatch(slice_messages(self.messages, 0, stop), self.decoded[:stop], rows, columnar)


def _mask(rows: npt.NDArray[np.int64], size: int) -> npt.NDArray[np.bool_]:
    mask = np.zeros(size, np.bool_)
    mask[rows] = True
    return mask


def columnar_decodings(columnar: ColumnarFrames, messages: MessageBatch) -> list[Decoding]:
    """The decoding of each frame of ``columnar`` (in its order) as the plain path makes it: its
    PDU parsed, its summary from the columns, its params named from the columns' names or, where
    no profile names it, from its PDU and its read's span (:func:`named_registers`). Frames that read
    alike share one decoding, as the annotator's repeats do."""
    frames = messages.frames
    data, offsets = frames.data, frames.offsets
    groups = columnar.groups or alike(columnar, data, offsets, messages.role)
    spelt = columnar if groups is None else columnar.take(groups.firsts)
    summaries = spelt.summaries(data)
    positions = spelt.positions
    starts, stops = offsets[positions].tolist(), offsets[positions + 1].tolist()
    roles = messages.role[positions].tolist()
    names = spelt.names
    named_params: list[tuple[ParamValue, ...] | None] = [None] * len(spelt)
    if names is not None:
        sizes = (np.maximum(spelt.count, 0) + spelt.read_count).tolist()
        entries, table, begin = names.row.tolist(), names.table, 0
        for place, size in enumerate(sizes):
            frame_entries = entries[begin : begin + size]
            begin += size
            if frame_entries and frame_entries[0] >= 0:
                named_params[place] = tuple(table[entry][0] for entry in frame_entries)
    decodings: list[Decoding] = []
    for place, (start, stop, role, summary, kind, function, address, count) in enumerate(zip(
            starts, stops, roles, summaries, spelt.kind.tolist(), spelt.function.tolist(), spelt.address.tolist(),
            spelt.count.tolist(), strict=True)):
        pdu = parse_as(data[start:stop], ROLE_ORDER[role])
        params = named_params[place]
        if params is not None:
            decodings.append(Decoding(summary, params, pdu))
        else:
            request = ReadRequest(function, address, count) if kind == READ_ANSWER else None
            decodings.append(Decoding(summary, named_registers(pdu, request), pdu))
    if groups is None:
        return decodings
    return list(map(decodings.__getitem__, groups.inverse.tolist()))


__all__ = ["AnnotatedBatch", "columnar_decodings"]
