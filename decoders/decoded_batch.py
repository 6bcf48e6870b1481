"""A decoded batch: framed and paired messages in columns with what each says.

The one form the annotator hands to every output (``Sink.messages``); built low in
``decoders/`` so that every output and every decoder can name it without a cycle.

Which frames of a batch are decoded in columns (:mod:`decoders.modbus.columnar`) and which one
by one depends on the frames alone (their function, shape and profile), never on the outputs:
every output gets the same batch, and reads it one way: :meth:`AnnotatedBatch.columns` gives what
the kept messages say as :class:`DecodedColumns` (a summary per frame, a long table of params,
each frame's protocol and remarks), whichever way they were decoded, frames alike given once;
:meth:`AnnotatedBatch.summaries` their summary lines, :meth:`AnnotatedBatch.message_params`
each message's params as objects (made from the same form). Only what reformats a PDU
(``--registers``) or iterates the batch takes each frame's :class:`~decoders.message.Decoding`,
which for a frame in columns is built when first asked for (:func:`columnar_decodings`).

This module is the outputs' one way into the decoded form: ``sniffer/`` imports nothing else of
:mod:`decoders.modbus` but the codec registry (:mod:`decoders.modbus.codecs`; an import-linter
contract holds it).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from decoders.message import ROLE_ORDER, Decoding, Message, MessageBatch, ParamValue, slice_messages
from decoders.modbus.alike import alike, mostly_distinct
from decoders.modbus.codecs import parse_as
from decoders.modbus.columnar import NO_VALUE, ColumnarFrames, ColumnarNames, ColumnarParams
from decoders.modbus.columnar_text import READ_ANSWER, summaries
from decoders.modbus.param_runs import named_registers
from decoders.modbus.pdu import ReadRequest

#: What the outputs read (see the module's docstring).
__all__ = ["AnnotatedBatch", "ColumnarNames", "ColumnarParams", "DecodedColumns", "Params", "columnar_decodings",
           "mostly_distinct", "remarked"]
Item = TypeVar("Item")
#: The params a frame names, as its decoding holds them.
Params = tuple[ParamValue, ...]


@dataclass(frozen=True, slots=True)
class AnnotatedBatch:
    """Decoded messages in columns: a :class:`MessageBatch` and each message's decoding.

    ``rows``: the positions kept (by a filter, a limit), ``None`` for all. What the kept
    messages say is read through :meth:`columns` (the one decoded form), :meth:`summaries` and
    :meth:`remarked_summaries`. ``columnar``: the kept frames decoded in columns
    (:meth:`Annotator.annotate_columnar`), whose entries of ``decoded`` are :data:`IN_COLUMNS`;
    :attr:`decodings` has them all as objects, those built when first read. Iterating yields the
    kept messages as objects.
    """

    messages: MessageBatch
    #: Each message's decoding as the annotator made it (:data:`IN_COLUMNS`: in ``columnar``).
    decoded: list[Decoding]
    rows: npt.NDArray[np.int64] | None = None
    columnar: ColumnarFrames | None = None
    #: :attr:`decodings` once built: a one-entry cache in a frozen batch, so that the readers of
    #: objects (``--registers``, iterating the batch) build them once between them.
    _built: list[list[Decoding]] = field(default_factory=list, compare=False, repr=False)
    #: :meth:`columns` once made: every writer of the batch reads the same.
    _columns: list[list[DecodedColumns]] = field(default_factory=list, compare=False, repr=False)
    #: :meth:`remarked_summaries` once made: the tables read them a block of rows at a time.
    _remarked: list[list[str]] = field(default_factory=list, compare=False, repr=False)
    #: :meth:`message_params` once made: the value readers share them.
    _params: list[list[Params]] = field(default_factory=list, compare=False, repr=False)

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

    def columns(self) -> list[DecodedColumns]:
        """What the kept messages say, in columns: those decoded one by one, then (where any)
        those in columns; each part's :attr:`~DecodedColumns.positions` say whose rows it has."""
        if not self._columns:
            parts: list[DecodedColumns] = [OneByOne(self)]
            if self.columnar is not None and len(self.columnar):
                parts.append(InColumns(self.columnar, self.messages))
            self._columns.append(parts)
        return self._columns[0]

    def summaries(self) -> list[str]:
        """Every kept message's summary line, in order."""
        return self.each_message(lambda part: part.summaries())

    def remarked_summaries(self) -> list[str]:
        """Every kept message's summary line with the profile's remarks after it (:func:`remarked`),
        made once per batch."""
        if not self._remarked:
            self._remarked.append(self.each_message(lambda part: part.remarked_summaries()))
        return self._remarked[0]

    def message_params(self) -> list[Params]:
        """The params each message names, by position (of every message: a write's answer reads
        its request's, kept or not; a frame in columns that is not kept names none), made once per
        batch from the decoded form. Frames that read alike share one tuple."""
        if not self._params:
            placed = np.empty(len(self.decoded), object)
            placed[:] = self.decoded_params()
            # Those in columns (the first part's are read from ``decoded``, kept or not).
            _place(placed, self.columns()[1:], lambda part: part.param_values())
            self._params.append(placed.tolist())
        return self._params[0]

    def decoded_params(self) -> list[Params]:
        """The params of the messages decoded one by one, by position (frames in columns: none):
        for readers that take those in columns from the columns."""
        return [decoding.params for decoding in self.decoded]

    def kept_at(self, values: list[Item], positions: npt.NDArray[np.int64]) -> list[Item]:
        """Of ``values`` (one per kept message, as :meth:`each_message` gives them), those of the
        kept messages at ``positions`` (in any order)."""
        rows = positions if self.rows is None else np.searchsorted(self.rows, positions)
        return list(map(values.__getitem__, rows.tolist()))

    def each_message(self, read: Callable[[DecodedColumns], Sequence[Item]]) -> list[Item]:
        """What ``read`` gives for each part of :meth:`columns`, one per kept message, in order."""
        parts = self.columns()
        if len(parts) == 1:  # its positions are the kept ones, in order
            alone = read(parts[0])
            return alone if isinstance(alone, list) else list(alone)
        placed = np.empty(len(self.messages), object)
        _place(placed, parts, read)
        each: list[Item] = (placed if self.rows is None else placed[self.rows]).tolist()
        return each

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


class DecodedColumns(ABC):
    """What some kept messages of a batch say, in columns: the one decoded form every writer
    reads (:meth:`AnnotatedBatch.columns`). Frames alike are given once: the rows here are those
    of the frames at :attr:`spelt_positions`, and :meth:`each` gives every frame its row's.
    Each column is made when first read."""

    def __init__(self, positions: npt.NDArray[np.int64], spelt_positions: npt.NDArray[np.int64],
                 inverse: npt.NDArray[np.int64] | None) -> None:
        #: The frames' positions in the batch, in order.
        self.positions = positions
        #: The positions of the frames given: one per group of frames alike.
        self.spelt_positions = spelt_positions
        #: For each frame, its row among those given (``None``: each its own).
        self.inverse = inverse
        self._summaries: list[str] | None = None
        self._params: ColumnarParams | None = None
        self._named: list[list[ParamValue] | None] = []
        self._param_values: list[Params] | None = None

    def summaries(self) -> list[str]:
        """Each frame's summary line."""
        return self.each(self.spelt_summaries())

    def remarked_summaries(self) -> list[str]:
        """Each frame's summary line with its remarks (:func:`remarked`); a frame in columns has none."""
        return self.summaries()

    def spelt_summaries(self) -> list[str]:
        """The summary line of each frame given."""
        if self._summaries is None:
            self._summaries = self._made_summaries()
        return self._summaries

    def params(self) -> ColumnarParams:
        """The params of the frames given, frame after frame; a ``name`` is an entry of :meth:`named`."""
        if self._params is None:
            self._params = self._made_params()
        return self._params

    def named(self) -> list[ParamValue] | None:
        """The params the ``name`` column of :meth:`params` refers to (``None``: none)."""
        if not self._named:
            self._named.append(self._made_named())
        return self._named[0]

    def param_values(self) -> list[Params]:
        """Each frame's params as objects (frames alike share a tuple): for readers that take
        a param's code, name, value and unit together."""
        return self.each(self.spelt_param_values())

    def spelt_param_values(self) -> list[Params]:
        """The params of each frame given, as objects."""
        if self._param_values is None:
            self._param_values = self._made_param_values()
        return self._param_values

    def protocols_and_remarks(self) -> list[tuple[int, tuple[str, ...]]] | None:
        """Each frame given's protocol and remarks (``None``: Modbus without remarks, every one)."""
        return None

    def each(self, given: list[Item]) -> list[Item]:
        """A value per frame from one per frame given: frames alike share theirs."""
        if self.inverse is None:
            return given
        # Taken in C, not by a ``map`` of ``__getitem__``.
        items = np.empty(len(given), object)
        items[:] = given
        each: list[Item] = items[self.inverse].tolist()
        return each

    @abstractmethod
    def _made_summaries(self) -> list[str]: ...

    @abstractmethod
    def _made_params(self) -> ColumnarParams: ...

    @abstractmethod
    def _made_named(self) -> list[ParamValue] | None: ...

    def _made_param_values(self) -> list[Params]:
        """The params of each frame given: a named param's entry of :meth:`named`, else its
        address and raw value (the address alone where the frame carries none)."""
        params = self.params()
        named = self.named() or []
        entries = [-1] * len(params.address) if params.name is None else params.name.tolist()
        made = [named[entry] if entry >= 0 else ParamValue(address) if value == NO_VALUE
                else ParamValue(address, None, None, value, value)
                for address, value, entry in zip(params.address.tolist(), params.value.tolist(), entries,
                                                 strict=True)]
        ends = np.cumsum(params.sizes).tolist()
        return [tuple(made[begin:end]) for begin, end in zip([0, *ends[:-1]], ends, strict=True)]


class InColumns(DecodedColumns):
    """The frames the annotator kept in columns (``columnar``; ``messages``: their batch), those
    that read alike (:func:`~decoders.modbus.alike.alike`: a drive's unchanged status, a request
    polled again) given once."""

    def __init__(self, columnar: ColumnarFrames, messages: MessageBatch | None = None, data: bytes = b"") -> None:
        self._data = data if messages is None else messages.frames.data
        found = None if messages is None else (
            columnar.groups or alike(columnar, self._data, messages.frames.offsets, messages.role))
        self.given = columnar if found is None else columnar.take(found.firsts)
        super().__init__(columnar.positions, self.given.positions, None if found is None else found.inverse)

    def _made_summaries(self) -> list[str]:
        return self.given.named_summaries(summaries(self.given, self._data))

    def _made_params(self) -> ColumnarParams:
        return self.given.params(self._data)

    def _made_named(self) -> list[ParamValue] | None:
        names = self.given.names
        return None if names is None else [param for param, _ in names.table]


class OneByOne(DecodedColumns):
    """The kept messages of ``batch`` decoded one by one, given once per :class:`Decoding` (the
    annotator shares one between frames of the same bytes, role and protocol); every param is
    named (an entry of :meth:`named`: the param itself)."""

    def __init__(self, batch: AnnotatedBatch) -> None:
        positions = batch.decoded_positions()
        decodings = batch.decoded_at(positions)
        ids = np.fromiter(map(id, decodings), np.uint64, len(decodings))
        _, firsts, inverse = np.unique(ids, return_index=True, return_inverse=True)
        kept = np.array(positions, np.int64)
        super().__init__(kept, kept[firsts], inverse.reshape(-1).astype(np.int64))
        self._all = decodings
        self._decodings: list[Decoding] = [decodings[first] for first in firsts.tolist()]
        self._protocols: list[int] = batch.messages.frames.protocols()[self.spelt_positions].tolist()

    def summaries(self) -> list[str]:
        """Each frame's summary line, read from its decoding (no group to look up)."""
        return [decoding.summary for decoding in self._all]

    def remarked_summaries(self) -> list[str]:
        return [remarked(decoding.summary, decoding.remarks) for decoding in self._all]

    def _made_summaries(self) -> list[str]:
        return [decoding.summary for decoding in self._decodings]

    def _made_params(self) -> ColumnarParams:
        named = self.named() or []
        sizes = np.fromiter((len(decoding.params) for decoding in self._decodings), np.int64, len(self._decodings))
        address = np.fromiter((param.address for param in named), np.int64, len(named))
        # Every param is named (given by itself): its raw word is not read from the column.
        return ColumnarParams(sizes, address, np.zeros(len(named), np.int64), np.arange(len(named), dtype=np.int64))

    def _made_named(self) -> list[ParamValue]:
        return [param for decoding in self._decodings for param in decoding.params]

    def param_values(self) -> list[Params]:
        return [decoding.params for decoding in self._all]

    def _made_param_values(self) -> list[Params]:
        return [decoding.params for decoding in self._decodings]

    def protocols_and_remarks(self) -> list[tuple[int, tuple[str, ...]]]:
        return [(protocol, decoding.remarks) for decoding, protocol in zip(self._decodings, self._protocols,
                                                                            strict=True)]


def remarked(summary: str, remarks: tuple[str, ...]) -> str:
    """A summary line with a profile's remarks after it, each after a ``⚠``, as the tables show it."""
    return " ⚠ ".join([summary, *remarks]) if remarks else summary


def _place(placed: npt.NDArray[np.object_], parts: list[DecodedColumns],
           read: Callable[[DecodedColumns], Sequence[object]]) -> None:
    """What ``read`` gives for each of ``parts``, put in ``placed`` (by position) at the part's
    positions: by numpy, where an object array takes a list's items as they are."""
    for part in parts:
        found = np.empty(len(part.positions), object)
        found[:] = read(part)
        placed[part.positions] = found


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
        laid = spelt.params(data)  # a value over several registers: one param
        assert laid.name is not None
        entries, table, begin = laid.name.tolist(), names.table, 0
        for place, size in enumerate(laid.sizes.tolist()):
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

