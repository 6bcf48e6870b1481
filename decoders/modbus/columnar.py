"""The commonest frames kept in columns: no PDU, decoding or param object for them.

A master's reads and writes and its slaves' answers are most frames of a bus; where the values
change, each is new to the annotator's memo and costs a PDU, a decoding and a param per value,
which an output that writes columns (the Parquet dataset) only takes apart again. Here such
frames of a batch are kept as columns (:class:`ColumnarFrames`, found by
:func:`decoders.modbus.columnar_find.find_columnar`): where each frame is, its function and
kind, the first address it names and how many values, where its values lie, and for an FC 23
request (a scanner's exchange: it writes some registers and reads others) the span it reads,
named after the one it writes.
:meth:`ColumnarFrames.summaries` writes their summary lines and :meth:`ColumnarFrames.values`
their values, as the PDUs, :mod:`decoders.modbus.param_runs` and the value rows' rule do. Where
a profile names a frame's slave, :class:`ColumnarNames` holds what it names of the params
(:mod:`decoders.profiles.column_names`), and the summaries end with their texts. The tests hold all
of it, and the annotator's state after each batch, to the plain path
(:meth:`Annotator.annotate_batch`).

Half the frames of a batch of mixed traffic, and nearly all of steady traffic, repeat one
another (a request polled again, a drive's unchanged status): :mod:`decoders.modbus.alike`
finds which read alike, so that they are named and spelt once per batch.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from operator import itemgetter
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct
from decoders.modbus.codecs import BIT_VALUES, BULK_SHAPES, BULK_SINGLE
from decoders.modbus.codes import MAX_QUANTITY
from decoders.modbus.columnar_text import READ_ANSWER, READ_WRITE, WRITE, WRITE_ANSWER, formatted, summaries, words_at
from decoders.modbus.pdu import COIL_ON
from decoders.profiles.naming import SHOWN_PARAMS, NamedValue, summary_with
from decoders.runs import spread, within_runs

#: A param's value where its frame names the address alone.
NO_VALUE = -1
#: A register's entry in :attr:`ColumnarNames.row` where it is a later register of a value over
#: several (a profile's ``f32``): the value's entry is at its first; the params leave it out.
PART_OF_VALUE = -2
#: Requests are read against by answers that come within this many frames of them.
KEPT_REQUESTS = 1024
#: A named value's text in the summary (``None``: it shows none).
_TEXT = itemgetter(1)
#: The most members :func:`one_of` compares values with one by one.
_FEW_MEMBERS = 8
#: The most a request may ask for, by function (0: not a function kept in columns).
MOST = np.zeros(257, np.int64)
for _function, _most in MAX_QUANTITY.items():
    MOST[_function] = _most


class Alike(NamedTuple):
    """Frames kept in columns that read alike (:func:`decoders.modbus.alike.alike`): ``firsts``, the first of each
    group (rows of the columns, ascending), and ``inverse``: for each frame, in order, its
    group's place among ``firsts``."""

    firsts: npt.NDArray[np.int64]
    inverse: npt.NDArray[np.int64]


class ColumnarValues(NamedTuple):
    """The values frames kept in columns carry, in the order the value rows' rule finds them
    (:mod:`sniffer.encoding.value_rows`), as runs: a frame's values one after another. Per run:
    ``frame``, the position of the frame that carries them; ``counts``, how many; ``found``,
    where they are found (a write's values: at its answer); ``written``, written, not reported;
    ``request``, the request's frame index (-1 for written values). Per value: its ``address``
    and ``raw`` value (a register's word; a coil as 0 or 1), 32 bits as the Parquet columns have
    them, and ``name``. A column of the runs is made one of the values by :meth:`each`: the
    writers repeat the few columns they need, rather than a row per value for every column."""

    frame: npt.NDArray[np.int64]
    counts: npt.NDArray[np.int64]
    found: npt.NDArray[np.int64]
    written: npt.NDArray[np.bool_]
    request: npt.NDArray[np.int64]
    address: npt.NDArray[np.int32]
    raw: npt.NDArray[np.int32]
    #: Each value's entry in the frames' :attr:`ColumnarNames.table` (-1: unnamed); ``None``: no
    #: frame is named.
    name: npt.NDArray[np.int64] | None = None

    def each(self, column: npt.NDArray[Any]) -> npt.NDArray[Any]:
        """``column`` (a value per run) as a value per value."""
        repeated: npt.NDArray[Any] = np.repeat(column, self.counts)
        return repeated


class ColumnarParams(NamedTuple):
    """The params of frames kept in columns, frame after frame: ``sizes``: how many each frame
    names; each param's ``address``, and its ``value`` (:data:`NO_VALUE` where the frame names the
    register or coil without one: a read request, the answer to a multiple write); ``name``: its
    entry in :attr:`ColumnarNames.table` (-1: unnamed; ``None``: no frame is named)."""

    sizes: npt.NDArray[np.int64]
    address: npt.NDArray[np.int64]
    value: npt.NDArray[np.int64]
    name: npt.NDArray[np.int64] | None = None


class ColumnarNames(NamedTuple):
    """What profiles name of the params of frames kept in columns
    (:mod:`decoders.profiles.column_names`): ``row``, per param in :meth:`ColumnarFrames.params` order,
    its entry (-1: its slave's profile adds nothing); ``table``: each named value (param and
    summary text) of the batch, once."""

    row: npt.NDArray[np.int64]
    table: list[NamedValue]

    def shown(self, sizes: npt.NDArray[np.int64]) -> tuple[
            list[str | None], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """What the frames' summaries show of their named values (``sizes``: how many params each
        frame names): the text of every entry (``None``: it shows none), the entries shown, frame
        after frame, and how many each frame shows."""
        named_texts = list(map(_TEXT, self.table))
        # Whether each entry shows a text, the last for -1 (none): a lookup of booleans, not a
        # comparison of every param's object with None.
        showing = np.concatenate([np.fromiter((text is not None for _, text in self.table), np.bool_, len(self.table)),
                                  [False]])
        shown = np.flatnonzero(showing[np.maximum(self.row, -1)])  # PART_OF_VALUE shows nothing
        return named_texts, self.row[shown], _counted(sizes, shown)

    def suffixed(self, texts: list[str], sizes: npt.NDArray[np.int64]) -> list[str]:
        """``texts`` (the frames' PDU summaries; ``sizes``: how many params each names) followed
        by their named values' texts, as :func:`~decoders.profiles.naming.summary_with` writes them:
        frames that show as many texts at once, by one ``%`` of a template each
        (:func:`~decoders.modbus.columnar_text.formatted`), or one by one where a text holds a
        newline, which ``formatted`` cuts at."""
        named_texts, entries, counts = self.shown(sizes)
        if not len(entries):
            return texts
        words = np.empty(len(named_texts), object)
        words[:] = named_texts
        said = words[entries]
        starts = np.cumsum(counts) - counts
        if "\n" in "".join(filter(None, named_texts)):
            each = said.tolist()
            for position in np.flatnonzero(counts).tolist():
                start = int(starts[position])
                texts[position] = summary_with(texts[position], each[start : start + int(counts[position])])
            return texts
        suffixed = np.empty(len(texts), object)
        suffixed[:] = texts
        for count in distinct(counts[counts > 0]).tolist():
            frames = np.flatnonzero(counts == count)
            template = "%s: " + ", ".join(["%s"] * min(count, SHOWN_PARAMS)) + (" …" if count > SHOWN_PARAMS else "")
            columns = [suffixed[frames]] + [said[starts[frames] + place] for place in range(min(count, SHOWN_PARAMS))]
            suffixed[frames] = formatted(template, [column.tolist() for column in columns])
        result: list[str] = suffixed.tolist()
        return result


@dataclass(frozen=True)
class ColumnarFrames:
    """The frames of a batch kept in columns, by position (ascending), one entry each.

    ``kind``: ``READ`` … ``READ_WRITE`` (:mod:`decoders.modbus.columnar_text`); ``address``
    and ``count``: the first register or coil a frame names and how many (a read's answer: its
    request's first, and how many values it carries of those asked; an FC 23 request: those it
    writes); ``read_address`` and ``read_count``: the registers an FC 23 request reads, named
    after those it writes (-1 and 0 for every other frame); ``data``: where the values'
    bytes start in the batch's data (``-1`` for a read request); ``request``: an answer's request
    (frame index, ``-1`` for a request); ``answer``: a write's answer (position). ``kept_requests``: positions of read
    requests no answer here reads; ``earlier_requests``: frame indexes of requests from before
    the batch that answers here read."""

    positions: npt.NDArray[np.int64]
    function: npt.NDArray[np.int64]
    kind: npt.NDArray[np.int64]
    address: npt.NDArray[np.int64]
    count: npt.NDArray[np.int64]
    read_address: npt.NDArray[np.int64]
    read_count: npt.NDArray[np.int64]
    data: npt.NDArray[np.int64]
    byte_count: npt.NDArray[np.int64]
    request: npt.NDArray[np.int64]
    answer: npt.NDArray[np.int64]
    kept_requests: npt.NDArray[np.int64]
    earlier_requests: list[int]
    #: The names profiles give the params (``None``: no frame's slave has a profile that names).
    names: ColumnarNames | None = None
    #: The frames that read alike (:func:`~decoders.modbus.alike.alike`), where naming grouped
    #: them (:func:`~decoders.profiles.column_names.named`) to name each group once; writers
    #: spell their texts by the same groups. ``None``: not grouped (no profile names a frame,
    #: or they are mostly distinct).
    groups: Alike | None = None

    def __len__(self) -> int:
        return len(self.positions)

    def kept(self) -> list[tuple[int, int, int, int]]:
        """Position, function, first address and count of each of ``kept_requests``."""
        at = np.searchsorted(self.positions, self.kept_requests)
        return list(zip(self.kept_requests.tolist(), self.function[at].tolist(), self.address[at].tolist(),
                        self.count[at].tolist(), strict=True))

    def summaries(self, data: bytes) -> list[str]:
        """Each frame's summary line, as its PDU's ``summary()`` writes it
        (:mod:`decoders.modbus.columnar_text`), with what its profile names."""
        return self.named_summaries(summaries(self, data))

    def named_summaries(self, texts: list[str]) -> list[str]:
        """``texts`` (each frame's summary as its PDU writes it) followed by what its profile
        names (:meth:`ColumnarNames.suffixed`; a new list)."""
        return list(texts) if self.names is None else self.names.suffixed(list(texts), self._sizes())

    def take(self, rows: npt.NDArray[np.int64]) -> ColumnarFrames:
        """The frames at ``rows`` (indexes of these columns, ascending) as columns of their own, to
        spell their texts: their names and groups taken along (the table shared); ``kept_requests``
        and ``earlier_requests`` stay the batch's."""
        names, groups = self.names, self.groups
        if names is not None:
            sizes = self._sizes()
            taken = spread(self._param_starts()[rows], sizes[rows])
            names = names._replace(row=names.row[taken])
        if groups is not None:
            # Each group's first among the rows taken (its first may not be one), in their order.
            _, firsts, inverse = np.unique(groups.inverse[rows], return_index=True, return_inverse=True)
            order = np.argsort(firsts)
            place = np.empty(len(order), np.int64)
            place[order] = np.arange(len(order))
            groups = Alike(firsts[order], place[inverse.reshape(-1)])
        return ColumnarFrames(self.positions[rows], self.function[rows], self.kind[rows], self.address[rows],
                              self.count[rows], self.read_address[rows], self.read_count[rows], self.data[rows],
                              self.byte_count[rows], self.request[rows], self.answer[rows], self.kept_requests,
                              self.earlier_requests, names, groups)

    def values(self, data: bytes) -> ColumnarValues:
        """The values of read answers, writes and the echoes of single writes (a write request's
        at its answer, before the answer's own)."""
        valued = self._valued()
        written = one_of(self.kind[valued], (WRITE, READ_WRITE))
        found = np.where(written, self.answer[valued], self.positions[valued])
        # The frames in the rows' order, so that each column is laid out once, in order, rather
        # than sorting the rows. Stable: a frame's values stay in order.
        order = np.lexsort((~written, found))
        valued, written, found = valued[order], written[order], found[order]
        counts, value = self._carried(data, valued)
        request = np.where(written, -1, self.request[valued])
        name = None if self.names is None else self.names.row[self._param_rows(valued, counts)]
        address = spread(self.address[valued], counts, dtype=np.int32)
        if name is not None and (name == PART_OF_VALUE).any():  # a value over several registers: one
            whole = name != PART_OF_VALUE
            counts = _counted(counts, whole)
            address, value, name = address[whole], value[whole], name[whole]
        return ColumnarValues(self.positions[valued], counts, found, written, request, address, value, name)

    def params(self, data: bytes) -> ColumnarParams:
        """Every frame's params as the plain path's decoding names them, laid end to end: for
        writers that spell them in columns, with no decoding per frame."""
        valued = self._valued()
        counts, value = self._carried(data, valued)
        sizes = self._sizes()
        values = np.full(int(sizes.sum()), NO_VALUE, np.int64)
        values[self._param_rows(valued, counts)] = value
        address = spread(self.address, sizes)
        if self.read_count.any():  # FC 23 requests: their read span after their written one
            place = within_runs(sizes)
            first_span = np.repeat(np.maximum(self.count, 0), sizes)
            read = np.flatnonzero(place >= first_span)
            address[read] = np.repeat(self.read_address, sizes)[read] + (place - first_span)[read]
        if self.names is None:
            return ColumnarParams(sizes, address, values)
        name = self.names.row
        if (name == PART_OF_VALUE).any():  # a value over several registers is one param
            whole = name != PART_OF_VALUE
            sizes = _counted(sizes, whole)
            address, values, name = address[whole], values[whole], name[whole]
        return ColumnarParams(sizes, address, values, name)

    def grouped_params(self, groups: Alike) -> npt.NDArray[np.int64]:
        """For each param of these frames (:meth:`params` order), where the same param of its
        group's first (``groups``: :func:`~decoders.modbus.alike.alike`'s) is among the params
        of the firsts."""
        sizes = self._sizes()
        first_sizes = sizes[groups.firsts]
        starts = np.cumsum(first_sizes) - first_sizes
        places: npt.NDArray[np.int64] = spread(starts[groups.inverse], sizes)
        return places

    def _param_rows(self, valued: npt.NDArray[np.int64], counts: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        """Where each value of :meth:`_carried` is among the params of :meth:`params`."""
        return spread(self._param_starts()[valued], counts)

    def _sizes(self) -> npt.NDArray[np.int64]:
        """How many params each frame names (its count, and an FC 23 request's read count; none
        where it has none)."""
        sizes: npt.NDArray[np.int64] = np.maximum(self.count, 0) + self.read_count
        return sizes

    def _param_starts(self) -> npt.NDArray[np.int64]:
        """Where each frame's params begin among those of :meth:`params`."""
        sizes = self._sizes()
        starts: npt.NDArray[np.int64] = np.cumsum(sizes) - sizes
        return starts

    def _valued(self) -> npt.NDArray[np.int64]:
        """Which frames carry values (indexes of these columns)."""
        kind = self.kind
        valued: npt.NDArray[np.int64] = np.flatnonzero((kind == READ_ANSWER) | (kind == WRITE) | (kind == READ_WRITE)
                                                       | ((kind == WRITE_ANSWER)
                                                          & (BULK_SHAPES[self.function] == BULK_SINGLE)))
        return valued

    def _carried(self, data: bytes, valued: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64],
                                                                              npt.NDArray[np.int32]]:
        """How many values each of the frames ``valued`` (:meth:`_valued`, in any order) carries,
        and the values, frame after frame (a register's word; a coil as 0 or 1). Coils and
        registers are each taken from their own frames' bytes only: a coil capture has a dozen
        values a frame, and reading every value both ways would triple the work."""
        counts = self.count[valued]
        function, starts = self.function[valued], self.data[valued]
        # Bits packed in bytes; a single coil's is a word (0xFF00: on), read with the registers.
        bit_frames = BIT_VALUES[function] & (BULK_SHAPES[function] != BULK_SINGLE)
        raw = np.frombuffer(data, np.uint8)
        if bit_frames.all():
            return counts, _bits(raw, starts, counts).astype(np.int32)
        values = np.empty(int(counts.sum()), np.int32)
        bit_rows = np.repeat(bit_frames, counts)
        if bit_frames.any():
            values[bit_rows] = _bits(raw, starts[bit_frames], counts[bit_frames])
        word_frames, word_rows = ~bit_frames, ~bit_rows
        words = words_at(raw, spread(starts[word_frames], counts[word_frames], 2))
        single_coil = np.repeat(BIT_VALUES[function[word_frames]], counts[word_frames])
        values[word_rows] = np.where(single_coil, words == COIL_ON, words)
        return counts, values


def joined(parts: list[tuple[int, int, ColumnarFrames | None]]) -> ColumnarFrames | None:
    """The columns of a batch decoded in parts (each part's first position, where its data starts
    in the batch's, and its columns), as one. Where a profile names frames of a part, every
    part's frames keep groups (each frame its own where its part had none): frames alike in
    their bytes but in parts named otherwise are never spelt as one."""
    found = [(start, at, columns) for start, at, columns in parts if columns is not None and len(columns)]
    if not found:
        return next((columns for _, _, columns in parts if columns is not None), None)
    if len(found) == 1 and found[0][0] == 0:
        return found[0][2]

    def stacked(name: str) -> npt.NDArray[np.int64]:
        return np.concatenate([getattr(columns, name) for _, _, columns in found])

    def shifted(name: str, in_data: bool = False) -> npt.NDArray[np.int64]:
        """A column of positions (or places in the data), -1 for none, each part's from its start."""
        pieces = [(getattr(columns, name), at if in_data else start) for start, at, columns in found]
        return np.concatenate([np.where(values >= 0, values + shift, -1) for values, shift in pieces])

    earlier = [index for _, _, columns in found for index in columns.earlier_requests]
    named = [columns for _, _, columns in found if columns.names is not None]
    names, groups = None, None
    if named:
        rows: list[npt.NDArray[np.int64]] = []
        table: list[NamedValue] = []
        for _, _, columns in found:
            size = int(columns._sizes().sum())
            if columns.names is None:
                rows.append(np.full(size, -1, np.int64))
            else:
                rows.append(np.where(columns.names.row >= 0, columns.names.row + len(table), columns.names.row))
                table += columns.names.table
        names = ColumnarNames(np.concatenate(rows), table)
        firsts, inverse, rows_before, firsts_before = [], [], 0, 0
        for _, _, columns in found:
            own = columns.groups or Alike(np.arange(len(columns)), np.arange(len(columns)))
            firsts.append(own.firsts + rows_before)
            inverse.append(own.inverse + firsts_before)
            rows_before, firsts_before = rows_before + len(columns), firsts_before + len(own.firsts)
        groups = Alike(np.concatenate(firsts), np.concatenate(inverse))
    return ColumnarFrames(shifted("positions"), stacked("function"), stacked("kind"), stacked("address"),
                          stacked("count"), stacked("read_address"), stacked("read_count"), shifted("data", True),
                          stacked("byte_count"), stacked("request"), shifted("answer"), shifted("kept_requests"),
                          earlier, names, groups)


def _counted(sizes: npt.NDArray[np.int64], kept: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    """How many of each group's rows ``kept`` keeps (a mask, or the rows' indexes; ``sizes``: how
    many rows each group has, one group after another)."""
    counts: npt.NDArray[np.int64] = np.bincount(np.repeat(np.arange(len(sizes)), sizes)[kept], minlength=len(sizes))
    return counts


def _bits(raw: npt.NDArray[np.uint8], starts: npt.NDArray[np.int64],
          counts: npt.NDArray[np.int64]) -> npt.NDArray[np.uint8]:
    """The first ``counts[i]`` bits from byte ``starts[i]`` of ``raw``, least significant first,
    frame after frame: their bytes unpacked at once, then the bits past each count (0 to 7, in
    its last byte) left out by a mask. The mask is set where those few bits lie, rather than
    each frame's bits taken by their places (a gather by an index per bit)."""
    sizes = (counts + 7) >> 3
    bits = np.unpackbits(raw[spread(starts, sizes)], bitorder="little")
    past = 8 * sizes - counts
    if not past.any():
        return bits
    kept = np.ones(len(bits), np.bool_)
    kept[spread(8 * np.cumsum(sizes) - past, past)] = False
    shown: npt.NDArray[np.uint8] = bits[kept]
    return shown


def one_of(values: npt.NDArray[np.integer], members: Collection[int]) -> npt.NDArray[np.bool_]:
    """Whether each of ``values`` is one of ``members``: for a few, their equalities or'ed
    (``np.isin`` sorts, which costs more for a few), for more ``np.isin``."""
    if len(members) > _FEW_MEMBERS:
        found: npt.NDArray[np.bool_] = np.isin(values, list(members))
        return found
    found = np.zeros(values.shape, np.bool_)
    for member in members:
        found |= values == member
    return found
