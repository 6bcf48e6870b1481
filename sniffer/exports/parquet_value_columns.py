"""The Parquet ``values`` table's columns, laid out once from the rows of a batch.

Rows come from two sources (:mod:`sniffer.exports.parquet_values`): the values of profiled
params decoded one by one (a block of them per decoding, which repeats share) and the values
laid out by numpy (runs no profile names, frames left in columns, whose params a profile may
name). Both are made here into the same form, :class:`LaidRows`: every number a numpy column,
every text an entry of a small table of texts (a block's param, a named value, a register's
code, name and unit) which each row points at. Joined in the order found, the rows become Arrow
columns once: one ``take`` per text column from its table. Joining Arrow columns instead
(concatenated, then taken in order) would copy every text twice.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.message import ParamValue
from decoders.runs import spread
from sniffer.encoding.value_rows import VALUE_KINDS, WRITTEN
from sniffer.exports.arrow_compute import taken
from sniffer.exports.parquet_export import dictionary, nullable, times
from sniffer.exports.parquet_values import CollectedValues, NumericValues, param_columns

_VALUE_KINDS = pa.array(VALUE_KINDS)  # made once, not for each batch's dictionary
#: The text columns, in the order of :attr:`LaidRows.texts`.
TEXT_COLUMNS = ("code", "name", "text", "unit")
#: A param naming nothing: the entry the rows no profile names take (null texts, valid). A param
#: without a raw value, a read request's, is in a batch's table too, but no value row takes it.
_NO_PARAM = ParamValue(0)
_NO_TEXTS: tuple[list[str | None], ...] = ([None], [None], [None], [None])


@dataclass(frozen=True)
class LaidRows:
    """Value rows in columns: numbers as numpy arrays (``no_value``: where ``value`` is null, a
    value told in words), texts as each row's ``entry`` in ``texts`` (code, name, text and unit
    of each entry, as :data:`TEXT_COLUMNS`)."""

    t_ns: npt.NDArray[np.int64]
    index: npt.NDArray[np.int64]
    slave: npt.NDArray[np.integer[Any]]
    kind: npt.NDArray[np.int32]
    address: npt.NDArray[np.integer[Any]]
    raw: npt.NDArray[np.integer[Any]]
    value: npt.NDArray[np.float64]
    no_value: npt.NDArray[np.bool_]
    request_index: npt.NDArray[np.int64]
    valid: npt.NDArray[np.bool_]
    #: ``None``: no row has a text (rows no profile names), nor a null ``value``.
    entry: npt.NDArray[np.int64] | None
    texts: tuple[list[str | None], ...]

    def entries(self) -> npt.NDArray[np.int64]:
        return np.zeros(len(self.t_ns), np.int64) if self.entry is None else self.entry


_NUMBER_COLUMNS = [name for name in LaidRows.__dataclass_fields__ if name not in ("entry", "texts")]


def value_columns(found: CollectedValues, numeric: NumericValues | None = None) -> tuple[
        npt.NDArray[np.int64], dict[str, pa.Array]]:
    """The ``values`` table: (t, index, slave, kind, address, code, name, raw, value, text, unit,
    request index, valid), a row per value, in the order found (``numeric``: more rows, of the
    frames left in columns); and each row's time."""
    if numeric is None or not len(numeric):
        rows = _named_rows(found)
    else:
        rows = _numeric_rows(numeric)
        if found.named:
            rows = _joined(_named_rows(found), rows, numeric, found)
    return rows.t_ns, _arrow(rows)


def _joined(named: LaidRows, numeric: LaidRows, laid_out: NumericValues, found: CollectedValues) -> LaidRows:
    """The rows of both, in the order found (where each was found, then found when)."""
    counts = np.fromiter(map(len, found.blocks), np.int64, len(found.blocks))
    numeric_found, numeric_order = laid_out.found_and_order()
    order = np.lexsort((np.concatenate([np.repeat(np.array(found.named_order, np.int64), counts), numeric_order]),
                        np.concatenate([np.repeat(np.array(found.named_at, np.int64), counts), numeric_found])))
    columns = {name: np.concatenate([getattr(named, name), getattr(numeric, name)])[order] for name in _NUMBER_COLUMNS}
    entry = np.concatenate([named.entries(), numeric.entries() + len(named.texts[0])])[order]
    texts = tuple(mine + theirs for mine, theirs in zip(named.texts, numeric.texts, strict=True))
    return LaidRows(**columns, entry=entry, texts=texts)


def _arrow(rows: LaidRows) -> dict[str, pa.Array]:
    """The table's columns of ``rows``."""
    no_text = pa.nulls(len(rows.t_ns), pa.string())  # one for every column without a text
    if rows.entry is None:
        texts = dict.fromkeys(TEXT_COLUMNS, no_text)
    else:
        entry = pa.array(rows.entry)
        texts = {column: no_text if all(each is None for each in table) else taken(pa.array(table, pa.string()), entry)
                 for column, table in zip(TEXT_COLUMNS, rows.texts, strict=True)}
    return {
        **times("t", rows.t_ns),
        "index": pa.array(rows.index, pa.int64()),
        "slave": pa.array(rows.slave, pa.int16()),
        "kind": dictionary(rows.kind, _VALUE_KINDS),
        "address": pa.array(rows.address, pa.int32()),
        "code": texts["code"],
        "name": texts["name"],
        "raw": pa.array(rows.raw, pa.int32()),
        "value": pa.array(rows.value, pa.float64(),
                          mask=None if rows.entry is None or not rows.no_value.any() else rows.no_value),
        "text": texts["text"],
        "unit": texts["unit"],
        "request_index": nullable(rows.request_index, pa.int64()),
        "valid": pa.array(rows.valid, pa.bool_()),
    }


def _named_rows(found: CollectedValues) -> LaidRows:
    """The rows of profiled params, a row per value; each distinct block is an entry of the texts
    once, and its rows point at it."""
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
    entry = spread(np.array(starts, np.int64), counts)
    own = list(zip(*found.named, strict=True)) or [()] * 5  # the rows' own columns

    def each(field: int) -> npt.NDArray[np.int64]:
        return np.repeat(np.array(own[field], np.int64), counts)

    address, code, name, raw, number, text, unit, valid = zip(*params, strict=True) if params else ([()] * 8)
    numbered, unnumbered = _numbers(number)
    return LaidRows(
        each(0), each(1), each(2), each(3).astype(np.int32), np.array(address, np.int64)[entry],
        np.array(raw, np.int64)[entry], numbered[entry], unnumbered[entry], each(4), np.array(valid, np.bool_)[entry],
        entry, (list(code), list(name), list(text), list(unit)))


def _numbers(number: Sequence[float | None]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """The ``value`` column's numbers (NaN where there is none), and where there is none (null)."""
    return (np.array([np.nan if each is None else each for each in number], np.float64),
            np.array([each is None for each in number], np.bool_))


def _numeric_rows(rows: NumericValues) -> LaidRows:
    """The rows laid out by numpy; where a profile names some (``rows.names``), theirs as
    :func:`~sniffer.exports.parquet_values.named_block` has them (reported, the CRC good)."""
    raw = rows.raw.astype(np.float64)
    if rows.names is None or not (rows.name >= 0).any():
        return LaidRows(rows.t_ns, rows.index, rows.slave, rows.kind, rows.address, rows.raw, raw,
                        np.zeros(len(rows), np.bool_), rows.request_index, rows.valid, None, _NO_TEXTS)
    names = rows.names
    code, name, number, text, unit, available = param_columns([param for param, _ in names.table] + [_NO_PARAM])
    numbered, unnumbered = _numbers(number)
    usable = np.array(available, np.bool_)
    unnamed = len(names.table)  # the entry of _NO_PARAM: the rows no profile names
    rows_named = rows.name >= 0
    entry = np.where(rows_named, rows.name, unnamed)
    value = np.where(rows_named, numbered[entry], raw)
    valid = rows.valid & (~rows_named | usable[entry] | (rows.kind == WRITTEN))
    return LaidRows(rows.t_ns, rows.index, rows.slave, rows.kind, rows.address, rows.raw, value,
                    rows_named & unnumbered[entry], rows.request_index, valid, entry, (code, name, text, unit))
