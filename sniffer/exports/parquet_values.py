"""The Parquet ``values`` table: a row per value a slave reported or was written, in the order
found (the rule of :mod:`sniffer.encoding.value_rows`).

Two sources make its rows: the frames decoded one by one (:class:`ValueCollector`: the params
frames share taken apart once, a tuple each, names and units as text), and the frames the
annotator left in columns (:func:`columnar_values`: laid out by numpy from the frames' bytes, no
object per frame; where a profile names them, each distinct named value of a batch is read once
and the rows take their code, name, value, text, unit and validity from it). Each row carries
the frame index where it was found (a written value is found at its answer), which puts the two
back in one order (:mod:`sniffer.exports.parquet_value_columns`).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch, ColumnarNames, Params
from decoders.memo import KeptByIdentity
from decoders.message import NONE, ParamValue
from sniffer.encoding.value_rows import REPORTED, VALUE_KINDS, WRITTEN, ValueRow, ValueRows

#: The params of one decoding as the ``values`` table holds them, a tuple per param: address,
#: code, name, raw, value (numbers), text (what a value says in words), unit, valid.
NamedBlock = tuple[tuple[object, ...], ...]
#: A named row's own columns: time, index, slave, kind (its code), request index (``NONE``).
NamedRow = tuple[int, int, int, int, int]
_KIND_CODES = {kind: code for code, kind in enumerate(VALUE_KINDS)}


@dataclass
class CollectedValues:
    """The value rows of some batches, in the order found: of profiled slaves' params, the row's
    own columns (``named``) and its decoding's params (``blocks``, one object per decoding and
    kind: repeats share it); ``named_order``: each row's place, ``named_at``: the frame index
    where each was found."""

    named: list[NamedRow] = field(default_factory=list)
    blocks: list[NamedBlock] = field(default_factory=list)
    named_order: list[int] = field(default_factory=list)
    named_at: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.named)


@dataclass(frozen=True)
class NumericValues:
    """Rows of values in columns, of frames left in columns, whose profiles may name them
    (``name``: each row's entry in ``names``, -1 where none does). Rows come in runs
    (``run_sizes``: the rows of each, one after the other), each found at once: the frame index
    where (``run_found``) and its place among what was found there (``run_order``); kept per
    run, the rows' own are made only where rows are put in order among others
    (:meth:`found_and_order`): for 1 M coil frames, two columns of 12.7 M rows fewer."""

    t_ns: npt.NDArray[np.int64]
    index: npt.NDArray[np.int64]
    #: Slaves, addresses and raw values: in the columns' own types where laid out by numpy
    #: (16 and 32 bits, so Arrow takes them as they are), 64 bits where collected.
    slave: npt.NDArray[np.integer[Any]]
    kind: npt.NDArray[np.int32]
    address: npt.NDArray[np.integer[Any]]
    raw: npt.NDArray[np.integer[Any]]
    request_index: npt.NDArray[np.int64]
    valid: npt.NDArray[np.bool_]
    name: npt.NDArray[np.int64]
    run_sizes: npt.NDArray[np.int64]
    run_found: npt.NDArray[np.int64]
    #: The place of each run among the rows found (for frames in columns, which are found where
    #: no other row is: 0 for a write's values, 1 for its answer's, as the rule has them).
    run_order: npt.NDArray[np.int64]
    #: What the rows' entries are (:class:`decoders.modbus.columnar.ColumnarNames`), ``None``: none.
    names: ColumnarNames | None = None

    def __len__(self) -> int:
        return len(self.t_ns)

    def found_and_order(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Each row's run's ``run_found`` and ``run_order``."""
        return np.repeat(self.run_found, self.run_sizes), np.repeat(self.run_order, self.run_sizes)


class ValueCollector(ValueRows):
    """The value rows of each batch's frames decoded one by one, taken by :meth:`take` (the
    ``values`` table, with the rows of frames in columns: :func:`columnar_values`); each row
    refers to its params' :data:`NamedBlock`, made once per batch for the frames that share them
    (the batch's frames of one decoding: a bus repeats its exceptions and identifications)."""

    def __init__(self) -> None:
        super().__init__()
        self._found = CollectedValues()
        self._rows_found = 0
        #: This batch's blocks of each frame's params, by kind and CRC verdict.
        self._blocks: KeptByIdentity[Params, dict[tuple[str, bool], NamedBlock]] = KeptByIdentity(_no_blocks)

    def messages(self, batch: AnnotatedBatch) -> None:
        """:meth:`ValueRows.messages` of the frames decoded one by one (those in columns:
        :func:`columnar_values`)."""
        self._blocks.kept.clear()
        self.rows_at(batch, batch.decoded_positions(), batch.decoded_params())

    def _block(self, params: Params, kind: str, crc_ok: bool) -> NamedBlock:
        """``params`` as the table holds them, made once per batch."""
        blocks = self._blocks.of(params)
        block = blocks.get((kind, crc_ok))
        if block is None:
            block = blocks[kind, crc_ok] = _named_block(params, written=kind == "written", crc_ok=crc_ok)
        return block

    def _emit(self, row: ValueRow, *, crc_ok: bool) -> None:
        """:meth:`ValueRows._emit` of every value (this collector chooses none), a frame's
        params taken apart once (``tests/test_parquet.py`` holds the table to ``values``)."""
        block = self._block(row.found, row.kind, crc_ok)
        if not block:
            return
        self.shown += len(block)
        found, self._rows_found = self._found, self._rows_found + 1
        found.named.append((row.t_ns, row.index, row.slave, _KIND_CODES[row.kind],
                            NONE if row.request_index is None else row.request_index))
        found.blocks.append(block)
        found.named_order.append(self._rows_found)
        found.named_at.append(self.emitting)

    def take(self) -> CollectedValues:
        found, self._found = self._found, CollectedValues()
        return found


def _no_blocks(params: Params) -> dict[tuple[str, bool], NamedBlock]:
    """The blocks of ``params`` before any is made."""
    return {}


def _named_block(params: tuple[ParamValue, ...], *, written: bool, crc_ok: bool) -> NamedBlock:
    """The values of ``params`` that carry a raw value, each valid as the rule says."""
    carried = [param for param in params if param.raw is not None]
    if not carried:
        return ()
    _, _, number, text, _, _ = param_columns(carried)
    # ``raw`` is the word at ``address``: a value over several registers gives its first (the
    # number is ``value``; JSONL's ``words`` has them all).
    return tuple((param.address, param.code, param.name, param.raw if param.words is None else param.words[0],
                  each_number, each_text, param.unit,
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
    each, written, count = rows.each, rows.written, len(rows.raw)
    index = rows.frame + first  # of each run's frame
    # Read-only: -1 for every row; no one writes a row's entry.
    name = np.broadcast_to(np.int64(-1), count) if rows.name is None else rows.name
    return NumericValues(each(frames.t_start_ns[rows.frame]), each(index), each(messages.slave[rows.frame]),
                         each(np.where(written, WRITTEN, REPORTED).astype(np.int32)), rows.address, rows.raw,
                         each(np.where(written, index, rows.request)), np.ones(count, np.bool_), name=name,
                         run_sizes=rows.counts, run_found=rows.found + first,
                         run_order=np.where(written, 0, 1).astype(np.int64), names=columnar.names)


def param_columns(params: list[ParamValue]) -> tuple[list[str | None], list[str | None], list[float | None],
                                                     list[str | None], list[str | None], list[bool]]:
    """The code, name, number (a coil's on or off: 1 or 0), text, unit and availability of each of ``params``
    (at least one), each column one pass in C or one comprehension: the one rule of what the
    ``value`` and ``text`` columns hold. Read from the params themselves: rows kept by each
    param's identity, looked up among the other work of a batch, cost more."""
    code, name, value, unit, available = map(list, zip(*map(_PARAM_FIELDS, params), strict=True))
    number = [float(each) if isinstance(each, int | float) else None for each in value]
    text = [each if isinstance(each, str) else None for each in value]
    return code, name, number, text, unit, available


_PARAM_FIELDS = operator.attrgetter("code", "name", "value", "unit", "available")
