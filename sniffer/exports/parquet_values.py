"""The Parquet ``values`` table: a row per value a slave reported or was written, in the order
found (the rule of :mod:`sniffer.encoding.value_rows`).

Three sources make its rows: values a profile names (a tuple each, names and units as text),
runs of values no profile names (laid out by numpy), and the frames the annotator left in
columns (``AnnotatedBatch.columnar``: laid out by numpy from the frames' bytes, no object per
frame; where a profile names them, each distinct named value of a batch is read once and the
rows take their code, name, value, text, unit and validity from it). Each row carries the frame index
where it was found (a written value is found at its answer), which puts the three back in one
order.
"""

from __future__ import annotations

import dataclasses
import itertools
import operator
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.memo import Memo
from decoders.message import NONE, AnnotatedBatch, Decoding, ParamValue
from decoders.modbus.annotate import KEPT_DECODINGS
from decoders.modbus.columnar import ColumnarNames, within_runs
from sniffer.encoding.value_rows import ValueRow, ValueRows
from sniffer.exports.parquet_export import dictionary, nullable, times
from sniffer.exports.value_bulk import REPORTED, VALUE_KINDS, WRITTEN, BulkRows, bulk_rows

#: The params of one decoding as the ``values`` table holds them, a tuple per param: address,
#: code, name, raw, value (numbers), text (what a value says in words), unit, valid.
NamedBlock = tuple[tuple[object, ...], ...]
_NAMED_COLUMNS = 8
#: While decodings do not repeat, one block in this many is kept in the memo, to find out when
#: they start to (see :class:`ValueCollector`).
PROBE_EVERY = 16
#: A named row's own columns: time, index, slave, kind (its code), request index (``NONE``).
NamedRow = tuple[int, int, int, int, int]
_KIND_CODES = {kind: code for code, kind in enumerate(VALUE_KINDS)}


@dataclass
class CollectedValues:
    """The value rows of some batches, in the order found: of profiled slaves' params, the row's
    own columns (``named``) and its decoding's params (``blocks``, one object per decoding and
    kind: repeats share it); the rows of runs as they are (``runs``); ``*_order``: each row's
    place, ``*_at``: the frame index where each was found."""

    named: list[NamedRow] = field(default_factory=list)
    blocks: list[NamedBlock] = field(default_factory=list)
    named_order: list[int] = field(default_factory=list)
    named_at: list[int] = field(default_factory=list)
    runs: list[ValueRow] = field(default_factory=list)
    run_order: list[int] = field(default_factory=list)
    run_at: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.named) + len(self.runs)

    def in_order(self) -> None:
        """The named rows put in the order found (where each was found, then found when)."""
        order = np.lexsort((np.array(self.named_order, np.int64), np.array(self.named_at, np.int64))).tolist()
        self.named = [self.named[row] for row in order]
        self.blocks = [self.blocks[row] for row in order]
        self.named_order = [self.named_order[row] for row in order]
        self.named_at = [self.named_at[row] for row in order]


@dataclass(frozen=True)
class NumericValues:
    """Rows of values in columns (``found``: the frame index each was found at): of runs no
    profile names, and of frames left in columns, whose profiles may name them (``name``: each
    row's entry in ``names``, -1 where none does)."""

    t_ns: npt.NDArray[np.int64]
    index: npt.NDArray[np.int64]
    slave: npt.NDArray[np.int64]
    kind: npt.NDArray[np.int32]
    address: npt.NDArray[np.int64]
    raw: npt.NDArray[np.int64]
    request_index: npt.NDArray[np.int64]
    valid: npt.NDArray[np.bool_]
    found: npt.NDArray[np.int64]
    #: The place of each row's run among the rows found (for frames in columns, which are found
    #: where no other row is: 0 for a write's values, 1 for its answer's, as the rule has them).
    order: npt.NDArray[np.int64]
    name: npt.NDArray[np.int64]
    #: What the rows' entries are (:class:`decoders.modbus.columnar.ColumnarNames`), ``None``: none.
    names: ColumnarNames | None = None

    def __len__(self) -> int:
        return len(self.t_ns)


#: The columns of :class:`NumericValues`, laid end to end by :func:`_in_order`.
_ROW_COLUMNS = [name for name in NumericValues.__dataclass_fields__ if name != "names"]


class ValueCollector(ValueRows):
    """The value rows of each batch, taken by :meth:`take` (the ``values`` table); rows of slaves
    no profile speaks for stay runs until :func:`value_columns` lays them out with numpy, rows of
    profiled params refer to their decoding's :data:`NamedBlock`, made once per decoding (a
    plant's drives report the same values again and again)."""

    takes_runs = True

    def __init__(self) -> None:
        super().__init__()
        self._found = CollectedValues()
        self._rows_found = 0
        self._blocks: Memo[tuple[Decoding, str, bool], NamedBlock] = Memo(KEPT_DECODINGS)
        #: Blocks found in the memo and made, since :meth:`take`; whether to keep every block
        #: made (values that repeat) or one in :data:`PROBE_EVERY` (values that do not: keeping
        #: them costs more than making them, yet a few tell when they start to repeat).
        self._hits = self._made = 0
        self._keeping = True
        #: Whether rows found in bulk were added since :meth:`take`.
        self._bulk = False

    def messages(self, batch: AnnotatedBatch) -> None:
        """:meth:`ValueRows.messages`, the rows of named params found in bulk where the rule needs
        no frame by frame state (:func:`sniffer.exports.value_bulk.bulk_rows`): a row from each
        decoding's block, looked up once per decoding. The other frames go by the rule, one by
        one, after them; :meth:`take` puts the rows in the order found."""
        positions = batch.positions()
        found = bulk_rows(batch, positions, pending=self._writes.keys())
        if found is None:
            self.rows_at(batch, positions)
            return
        decodings, first = batch.decodings_at(positions), batch.messages.frames.first_index
        for rows in (found.written, found.reported):
            self._add_bulk(batch, rows, [decodings[row] for row in rows.carrier.tolist()], first)
        self.rows_at(batch, [positions[row] for row in found.one_by_one.tolist()])

    def _add_bulk(self, batch: AnnotatedBatch, rows: BulkRows, decodings: list[Decoding], first: int) -> None:
        """``rows`` (``decodings``: their carriers'), each row where its block has values."""
        if not len(rows.carrier):
            return
        kind = VALUE_KINDS[rows.kind]
        blocks: dict[tuple[int, bool], NamedBlock] = {}
        chosen = []
        for decoding, valid in zip(decodings, rows.valid.tolist(), strict=True):
            block = blocks.get((id(decoding), valid))
            if block is None:
                block = blocks[(id(decoding), valid)] = self._block(decoding, kind, valid)
            chosen.append(block)
        carried = np.fromiter(map(len, chosen), np.int64, len(chosen))
        kept = np.flatnonzero(carried > 0)
        if not len(kept):
            return
        messages = batch.messages
        carrier, count = rows.positions[kept], len(kept)
        request = np.full(count, first, np.int64) + carrier if rows.kind == WRITTEN else \
            messages.request_index[carrier]
        found = self._found
        found.named += zip(messages.frames.t_start_ns[carrier].tolist(), (carrier + first).tolist(),
                           messages.slave[carrier].tolist(), itertools.repeat(rows.kind, count), request.tolist(),
                           strict=False)
        found.blocks += [chosen[row] for row in kept.tolist()]
        found.named_order += range(self._rows_found + 1, self._rows_found + 1 + count)
        found.named_at += (rows.at[kept] + first).tolist()
        self._rows_found += count
        self.shown += int(carried.sum())
        self._bulk = True

    def _block(self, decoding: Decoding, kind: str, crc_ok: bool) -> NamedBlock:
        """The params of ``decoding`` as the table holds them, from the memo where kept."""
        key = (decoding, kind, crc_ok)
        block = self._blocks.get(key)
        if block is None:
            block = _named_block(decoding.params, written=kind == "written", crc_ok=crc_ok)
            self._made += 1
            if self._keeping or self._made % PROBE_EVERY == 0:
                self._blocks.put(key, block)
        else:
            self._hits += 1
        return block

    def _emit(self, row: ValueRow, *, crc_ok: bool) -> None:
        """:meth:`ValueRows._emit` of every value (this collector chooses none), a decoding's
        params taken apart once (``tests/test_parquet.py`` holds the table to ``values``)."""
        decoding = row.decoding
        if decoding is None:
            super()._emit(row, crc_ok=crc_ok)
            return
        block = self._block(decoding, row.kind, crc_ok)
        if not block:
            return
        self.shown += len(block)
        found, self._rows_found = self._found, self._rows_found + 1
        found.named.append((row.t_ns, row.index, row.slave, _KIND_CODES[row.kind],
                            NONE if row.request_index is None else row.request_index))
        found.blocks.append(block)
        found.named_order.append(self._rows_found)
        found.named_at.append(self.emitting)

    def output(self, row: ValueRow) -> None:
        """A row of runs (the rows of params go by :meth:`_emit`)."""
        found, self._rows_found = self._found, self._rows_found + 1
        found.runs.append(row)
        found.run_order.append(self._rows_found)
        found.run_at.append(self.emitting)

    def take(self) -> CollectedValues:
        found, self._found = self._found, CollectedValues()
        if self._bulk:
            found.in_order()
            self._bulk = False
        if self._hits + self._made >= PROBE_EVERY:
            # Kept, a block must be asked for again to pay: when probes are, keep them all.
            self._keeping = self._hits * (1 if self._keeping else PROBE_EVERY) >= self._made
            self._hits = self._made = 0
        return found


def _named_block(params: tuple[ParamValue, ...], *, written: bool, crc_ok: bool) -> NamedBlock:
    """The values of ``params`` that carry a raw value, each valid as the rule says."""
    carried = [param for param in params if param.raw is not None]
    if not carried:
        return ()
    _, _, number, text, _, _ = _named_columns_of(carried)
    return tuple((param.address, param.code, param.name, param.raw, each_number, each_text, param.unit,
                  crc_ok and (param.available or written))
                 for param, each_number, each_text in zip(carried, number, text, strict=True))


def columnar_values(batch: AnnotatedBatch) -> NumericValues | None:
    """The values of the frames left in columns (every one valid: their CRC holds, and a write
    kept in columns was confirmed)."""
    columnar = batch.columnar
    if columnar is None:
        return None
    messages, frames = batch.messages, batch.messages.frames
    first = frames.first_index
    rows = columnar.values(frames.data)
    index = rows.frame + first
    names = columnar.names
    return NumericValues(frames.t_start_ns[rows.frame], index, messages.slave[rows.frame].astype(np.int64),
                         np.where(rows.written, WRITTEN, REPORTED).astype(np.int32), rows.address, rows.raw,
                         np.where(rows.written, index, rows.request), np.ones(len(index), np.bool_),
                         found=rows.found + first, order=np.where(rows.written, 0, 1),
                         name=np.full(len(index), -1, np.int64) if rows.name is None else rows.name,
                         names=names)


def value_columns(found: CollectedValues, numeric: NumericValues | None = None) -> tuple[
        npt.NDArray[np.int64], dict[str, pa.Array]]:
    """The ``values`` table: (t, index, slave, kind, address, code, name, raw, value, text, unit,
    request index, valid), a row per value, in the order found (``numeric``: more rows, of the
    frames left in columns)."""
    parts = [] if numeric is None or not len(numeric) else [numeric]
    if found.runs:
        parts.insert(0, _run_values(found))
    if not parts:
        return _named_columns(found)[:2]
    laid_out = parts[0] if len(parts) == 1 else _in_order(parts)
    numeric_t, numeric_columns = _numeric_columns(laid_out)
    if not found.named:
        return numeric_t, numeric_columns
    named_t, named_columns, named_counts = _named_columns(found)
    order = np.lexsort((np.concatenate([np.repeat(np.array(found.named_order, np.int64), named_counts),
                                        laid_out.order]),
                        np.concatenate([np.repeat(np.array(found.named_at, np.int64), named_counts),
                                        laid_out.found])))
    taken = pa.array(order)
    columns = {name: pa.concat_arrays([named_columns[name], numeric_columns[name]]).take(taken)
               for name in named_columns}
    return np.concatenate([named_t, numeric_t])[order], columns


def _in_order(parts: list[NumericValues]) -> NumericValues:
    """The rows of ``parts`` as one, in the order found."""
    joined = {name: np.concatenate([getattr(part, name) for part in parts]) for name in _ROW_COLUMNS}
    order = np.lexsort((joined["order"], joined["found"]))
    names = next((part.names for part in parts if part.names is not None), None)
    return NumericValues(**{name: column[order] for name, column in joined.items()}, names=names)


def _named_columns(found: CollectedValues) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array],
                                                    npt.NDArray[np.int64]]:
    """The columns of the rows of profiled params, a row per value; and the values per row. Each
    distinct block is laid out once, and the rows take from it."""
    table: dict[int, int] = {}  # by the block's id (every block is held by ``found``): its first row
    params: list[tuple[object, ...]] = []
    starts = []
    for block in found.blocks:
        start = table.get(id(block))
        if start is None:
            start = table[id(block)] = len(params)
            params += block
        starts.append(start)
    counts = np.fromiter(map(len, found.blocks), np.int64, len(found.blocks))
    total = int(counts.sum())
    taken = None if len(params) == total else pa.array(  # None: no block twice, the table is the rows
        np.repeat(np.array(starts, np.int64), counts) + within_runs(counts))

    def column(values: tuple[object, ...], kind: pa.DataType) -> pa.Array:
        array = pa.array(values, kind)
        return array if taken is None else array.take(taken)

    own = list(zip(*found.named, strict=True)) or [()] * 5  # the rows' own columns

    def each(field: int) -> npt.NDArray[np.int64]:
        return np.repeat(np.array(own[field], np.int64), counts)

    t_ns = each(0)
    address, code, name, raw, number, text, unit, valid = zip(*params, strict=True) if params else (
        [()] * _NAMED_COLUMNS)
    return t_ns, {
        "t": times(t_ns),
        "index": pa.array(each(1), pa.int64()),
        "slave": pa.array(each(2), pa.int16()),
        "kind": dictionary(each(3).astype(np.int32), pa.array(VALUE_KINDS)),
        "address": column(address, pa.int32()),
        "code": column(code, pa.string()),
        "name": column(name, pa.string()),
        "raw": column(raw, pa.int32()),
        "value": column(number, pa.float64()),
        "text": column(text, pa.string()),
        "unit": column(unit, pa.string()),
        "request_index": nullable(each(4), pa.int64()),
        "valid": column(valid, pa.bool_()),
    }, counts


def _run_values(found: CollectedValues) -> NumericValues:
    """The rows of runs, laid out by numpy."""
    rows = found.runs
    runs = [run for row in rows for run in row.runs or ()]
    run_counts = np.array([run.size for run in runs], np.int64)
    counts = np.array([sum(run.size for run in row.runs or ()) for row in rows], np.int64)
    total = int(run_counts.sum())
    address = np.repeat(np.array([run.address for run in runs], np.int64), run_counts) + within_runs(run_counts)
    request = [NONE if row.request_index is None else row.request_index for row in rows]

    def each(values: Sequence[int]) -> npt.NDArray[np.int64]:
        return np.repeat(np.array(values, np.int64), counts)

    return NumericValues(
        each([row.t_ns for row in rows]), each([row.index for row in rows]), each([row.slave for row in rows]),
        np.repeat(np.array([VALUE_KINDS.index(row.kind) for row in rows], np.int32), counts), address,
        np.fromiter(itertools.chain.from_iterable(run.values or () for run in runs), np.int64, total),
        each(request), np.repeat(np.array([row.valid[0] for row in rows], np.bool_), counts), each(found.run_at),
        each(found.run_order), np.full(total, -1, np.int64))


def _numeric_columns(rows: NumericValues) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array]]:
    if rows.names is not None and (rows.name >= 0).any():
        return _with_names(rows, rows.names)
    no_text = pa.nulls(len(rows), pa.string())
    return rows.t_ns, {
        "t": times(rows.t_ns),
        "index": pa.array(rows.index, pa.int64()),
        "slave": pa.array(rows.slave, pa.int16()),
        "kind": dictionary(rows.kind, pa.array(VALUE_KINDS)),
        "address": pa.array(rows.address, pa.int32()),
        "code": no_text,
        "name": no_text,
        "raw": pa.array(rows.raw, pa.int32()),
        "value": pa.array(rows.raw.astype(np.float64), pa.float64()),
        "text": no_text,
        "unit": no_text,
        "request_index": nullable(rows.request_index, pa.int64()),
        "valid": pa.array(rows.valid, pa.bool_()),
    }


def _with_names(rows: NumericValues, names: ColumnarNames) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array]]:
    """:func:`_numeric_columns` where a profile names some rows: theirs as :func:`_named_block`
    has them (reported, the CRC good), each named value's read once and taken by the rows; the
    plain numbers named in arrays (``names.numbers``) from their registers' code, name and unit."""
    t_ns, columns = _numeric_columns(dataclasses.replace(rows, names=None))
    code, name, number, text, unit, available = _named_columns_of([param for param, _ in names.table] + [_NO_PARAM])
    numbers, registers = names.numbers, [] if names.numbers is None else names.numbers.registers
    numbered = np.array(number, np.float64)  # None: NaN, masked below
    unnumbered = np.array([value is None for value in number], np.bool_)
    usable = np.array(available, np.bool_)
    if numbers is not None:  # a plain number is a number, available
        numbered = np.concatenate([numbered, numbers.value])
        unnumbered = np.concatenate([unnumbered, np.zeros(len(numbers), np.bool_)])
        usable = np.concatenate([usable, np.ones(len(numbers), np.bool_)])
    # Entries laid out as the table's, the one naming nothing (the rows no profile names), the numbers'.
    unnamed = len(names.table)
    rows_named = rows.name >= 0
    entry = np.where(rows_named, rows.name + (rows.name >= unnamed), unnamed)
    taken = pa.array(entry)
    number_registers = None if numbers is None else pa.array(numbers.register)

    def picked(column: list[str | None], each_register: list[str | None]) -> pa.Array:
        texts = pa.array(column, pa.string())
        if number_registers is not None:
            texts = pa.concat_arrays([texts, pa.array(each_register, pa.string()).take(number_registers)])
        return texts.take(taken)

    value = np.where(rows_named, numbered[entry], rows.raw.astype(np.float64))
    valid = rows.valid & (~rows_named | usable[entry] | (rows.kind == WRITTEN))
    columns.update(code=picked(code, [plain.code for plain in registers]),
                   name=picked(name, [plain.name for plain in registers]),
                   text=picked(text, [None] * len(registers)), unit=picked(unit, [plain.unit for plain in registers]),
                   value=pa.array(value, pa.float64(), mask=rows_named & unnumbered[entry]),
                   valid=pa.array(valid, pa.bool_()))
    return t_ns, columns


def _named_columns_of(params: list[ParamValue]) -> tuple[list[str | None], list[str | None], list[float | None],
                                                         list[str | None], list[str | None], list[bool]]:
    """The code, name, number (not a bool), text, unit and availability of each of ``params``
    (at least one), each column one pass in C or one comprehension: the one rule of what the
    ``value`` and ``text`` columns hold. Read from the params themselves: rows kept by each
    param's identity, looked up among the other work of a batch, cost more (0.65 to 0.67 s
    against 0.53 to 0.55 s for 1 M mixed frames)."""
    code, name, value, unit, available = map(list, zip(*map(_PARAM_FIELDS, params), strict=True))
    number = [float(each) if isinstance(each, int | float) and not isinstance(each, bool) else None for each in value]
    text = [each if isinstance(each, str) else None for each in value]
    return code, name, number, text, unit, available


_PARAM_FIELDS = operator.attrgetter("code", "name", "value", "unit", "available")
#: A param naming nothing: the entry the rows no profile names take (null texts, valid). A param
#: without a raw value, a read request's, is in a batch's table too, but no value row takes it.
_NO_PARAM = ParamValue(0)
