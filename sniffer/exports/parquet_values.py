"""The Parquet ``values`` table: a row per value a slave reported or was written, in the order
found (the rule of :mod:`sniffer.encoding.value_rows`).

Three sources make its rows: values a profile names (a tuple each, names and units as text),
runs of values no profile names (laid out by numpy), and the frames the annotator left in
columns (``AnnotatedBatch.columnar``: laid out by numpy from the frames' bytes, no object per
frame). Each row carries the frame index where it was found (a written value is found at its
answer), which puts the three back in one order.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.message import NONE, AnnotatedBatch
from decoders.stats import Statistics
from sniffer.encoding.value_rows import ValueRow, ValueRows
from sniffer.exports.parquet_export import dictionary, nullable, times

#: A value row as the ``values`` table holds it (from a profiled slave's params).
ValueTuple = tuple[int, int, int, str, int, str | None, str | None, int | None, object, str | None, int | None, bool]
_VALUE_KINDS = ["reported", "written"]
_REPORTED, _WRITTEN = _VALUE_KINDS.index("reported"), _VALUE_KINDS.index("written")


@dataclass
class CollectedValues:
    """The value rows of some batches, in the order found: a tuple a value for profiled slaves'
    params (``tuples``), the rows of runs as they are (``runs``); ``*_order``: each one's place,
    ``*_at``: the frame index where each was found."""

    tuples: list[ValueTuple] = field(default_factory=list)
    tuple_order: list[int] = field(default_factory=list)
    tuple_at: list[int] = field(default_factory=list)
    runs: list[ValueRow] = field(default_factory=list)
    run_order: list[int] = field(default_factory=list)
    run_at: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.tuples) + len(self.runs)


@dataclass(frozen=True)
class NumericValues:
    """Rows of values no profile names, in columns (``found``: the frame index each was found at)."""

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

    def __len__(self) -> int:
        return len(self.t_ns)


class ValueCollector(ValueRows):
    """The value rows of each batch, taken by :meth:`take` (the ``values`` table); rows of slaves
    no profile speaks for stay runs until :func:`value_columns` lays them out with numpy."""

    takes_runs = True

    def __init__(self) -> None:
        super().__init__()
        self._found = CollectedValues()
        self._rows_found = 0

    def output(self, row: ValueRow) -> None:
        found, self._rows_found = self._found, self._rows_found + 1
        if row.runs is not None:
            found.runs.append(row)
            found.run_order.append(self._rows_found)
            found.run_at.append(self.emitting)
            return
        found.tuples.extend((row.t_ns, row.index, row.slave, row.kind, p.address, p.code, p.name, p.raw, p.value,
                             p.unit, row.request_index, valid) for p, valid in zip(row.params, row.valid, strict=True))
        found.tuple_order += [self._rows_found] * len(row.params)
        found.tuple_at += [self.emitting] * len(row.params)

    def take(self) -> CollectedValues:
        found, self._found = self._found, CollectedValues()
        return found

    def finish(self, statistics: Statistics) -> None:
        super().finish(statistics)


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
    return NumericValues(frames.t_start_ns[rows.frame], index, messages.slave[rows.frame].astype(np.int64),
                         np.where(rows.written, _WRITTEN, _REPORTED).astype(np.int32), rows.address, rows.raw,
                         np.where(rows.written, index, rows.request), np.ones(len(index), np.bool_),
                         found=rows.found + first, order=np.where(rows.written, 0, 1))


def value_columns(found: CollectedValues, numeric: NumericValues | None = None) -> tuple[
        npt.NDArray[np.int64], dict[str, pa.Array]]:
    """The ``values`` table: (t, index, slave, kind, address, code, name, raw, value, text, unit,
    request index, valid), a row per value, in the order found (``numeric``: more rows, of the
    frames left in columns)."""
    parts = [] if numeric is None or not len(numeric) else [numeric]
    if found.runs:
        parts.insert(0, _run_values(found))
    if not parts:
        return _tuple_columns(found.tuples)
    laid_out = parts[0] if len(parts) == 1 else _in_order(parts)
    numeric_t, numeric_columns = _numeric_columns(laid_out)
    if not found.tuples:
        return numeric_t, numeric_columns
    tuples_t, tuple_columns = _tuple_columns(found.tuples)
    order = np.lexsort((np.concatenate([np.array(found.tuple_order, np.int64), laid_out.order]),
                        np.concatenate([np.array(found.tuple_at, np.int64), laid_out.found])))
    taken = pa.array(order)
    columns = {name: pa.concat_arrays([tuple_columns[name], numeric_columns[name]]).take(taken)
               for name in tuple_columns}
    return np.concatenate([tuples_t, numeric_t])[order], columns


def _in_order(parts: list[NumericValues]) -> NumericValues:
    """The rows of ``parts`` as one, in the order found."""
    joined = [np.concatenate([getattr(part, name) for part in parts]) for name in NumericValues.__dataclass_fields__]
    rows = NumericValues(*joined)
    order = np.lexsort((rows.order, rows.found))
    return NumericValues(*(column[order] for column in joined))


def _tuple_columns(rows: Sequence[ValueTuple]) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array]]:
    t_ns = np.fromiter((row[0] for row in rows), np.int64, len(rows))
    values = [row[8] for row in rows]
    numbers = [float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None
               for value in values]
    kinds = np.array([_VALUE_KINDS.index(row[3]) for row in rows], np.int32)
    return t_ns, {
        "t": times(t_ns),
        "index": pa.array([row[1] for row in rows], pa.int64()),
        "slave": pa.array([row[2] for row in rows], pa.int16()),
        "kind": dictionary(kinds, pa.array(_VALUE_KINDS)),
        "address": pa.array([row[4] for row in rows], pa.int32()),
        "code": pa.array([row[5] for row in rows], pa.string()),
        "name": pa.array([row[6] for row in rows], pa.string()),
        "raw": pa.array([row[7] for row in rows], pa.int32()),
        "value": pa.array(numbers, pa.float64()),
        "text": pa.array([value if isinstance(value, str) else None for value in values], pa.string()),
        "unit": pa.array([row[9] for row in rows], pa.string()),
        "request_index": pa.array([row[10] for row in rows], pa.int64()),
        "valid": pa.array([row[11] for row in rows], pa.bool_()),
    }


def _run_values(found: CollectedValues) -> NumericValues:
    """The rows of runs, laid out by numpy."""
    rows = found.runs
    runs = [run for row in rows for run in row.runs or ()]
    run_counts = np.array([run.size for run in runs], np.int64)
    counts = np.array([sum(run.size for run in row.runs or ()) for row in rows], np.int64)
    total = int(run_counts.sum())
    first_of_run = np.repeat(np.cumsum(run_counts) - run_counts, run_counts)
    address = np.repeat(np.array([run.address for run in runs], np.int64), run_counts) + np.arange(total) - first_of_run
    request = [NONE if row.request_index is None else row.request_index for row in rows]

    def each(values: Sequence[int]) -> npt.NDArray[np.int64]:
        return np.repeat(np.array(values, np.int64), counts)

    return NumericValues(
        each([row.t_ns for row in rows]), each([row.index for row in rows]), each([row.slave for row in rows]),
        np.repeat(np.array([_VALUE_KINDS.index(row.kind) for row in rows], np.int32), counts), address,
        np.fromiter(itertools.chain.from_iterable(run.values or () for run in runs), np.int64, total),
        each(request), np.repeat(np.array([row.valid[0] for row in rows], np.bool_), counts), each(found.run_at),
        each(found.run_order))


def _numeric_columns(rows: NumericValues) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array]]:
    no_text = pa.nulls(len(rows), pa.string())
    return rows.t_ns, {
        "t": times(rows.t_ns),
        "index": pa.array(rows.index, pa.int64()),
        "slave": pa.array(rows.slave, pa.int16()),
        "kind": dictionary(rows.kind, pa.array(_VALUE_KINDS)),
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
