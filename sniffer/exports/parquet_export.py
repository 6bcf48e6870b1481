"""Decoded traffic as a Parquet dataset for SQL engines: ``export CAPTURE --parquet DIR``.

Five tables, each a folder of ``DIR`` partitioned the Hive way by bus and UTC date, so that
DuckDB, Polars, pyarrow datasets, Spark and Trino read a table as one, whatever number of
captures it holds::

    DIR/frames/bus=line-3/date=2026-03-01/<capture id>.parquet
    DIR/transactions/…   DIR/values/…   DIR/anomalies/…   DIR/latencies/…

* ``frames``: a row per frame (the JSONL frame record's facts: times, slave, function, role,
  CRC, flags, pairing, latency, the bytes, the summary);
* ``transactions``: a row per request and what became of it (the MCAP export's transactions);
* ``values``: a row per value a slave reported or was written (long form, the rule of
  ``rtusniff values``: :mod:`sniffer.encoding.value_rows`), numbers in ``value``, texts (state
  words, markers) in ``text``;
* ``anomalies``: a row per anomaly of a frame, by kind (:mod:`decoders.anomalies`: what
  ``stats`` counts);
* ``latencies``: the answers' latencies as histograms by slave and function, the bins of
  ``stats`` (:mod:`sniffer.exports.parquet_latencies`): a plant's percentiles without reading
  every answer.

Times are microsecond UTC timestamps (``t``), each beside its exact nanoseconds since 1970 as an
integer (``t_ns``), so that every engine reads them as written; columns are zstd-compressed; each
file's key-value metadata holds the capture's provenance (source files and SHA-256, line, timing,
tool version, command).
A capture's files are named by its id (the first 16 hex digits of its SHA-256) and created
exclusively: exporting more captures adds files and never rewrites one, and a capture already
in the dataset is refused. Files are written beside their name and put in place once whole.

Row groups are compressed and written by a thread of their own, in order, while the next rows are
decoded (:mod:`sniffer.exports.parquet_writing`).
"""

from __future__ import annotations

import contextlib
import functools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.parquet as pq

from decoders.anomalies import KINDS, anomaly_masks
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import flag_names_of
from decoders.message import NONE, ROLE_ORDER
from decoders.runs import spread
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports import TABLES
from sniffer.exports.latency_bins import DAY_NS
from sniffer.exports.parquet_summaries import Summaries
from sniffer.exports.parquet_writing import RowGroupWriter
from sniffer.exports.transactions import OUTCOMES

#: What a bus name may hold: it names a folder (``bus=NAME``) that every engine reads back as is.
_BUS_NAME = re.compile(r"[^\x00-\x1f\x7f/\\=:*?\"<>|]{1,100}")


def bus_name_fault(name: str) -> str | None:
    """Why ``name`` cannot name a bus partition; ``None`` when it can."""
    if not _BUS_NAME.fullmatch(name) or not name.isprintable():
        return ("a bus name is 1 to 100 printable characters without '/', '\\', '=', ':', '*', '?', '\"', '<', '>', "
                "'|' or a control character")
    if name.strip(". ") == "" or name != name.strip():
        return "a bus name is more than dots, and neither begins nor ends with a space"
    return None


#: Rows gathered per file before they are written as a row group.
ROW_GROUP_ROWS = 1 << 17
#: Time columns: microsecond UTC timestamps, the type every engine reads without settings (Spark
#: refuses Parquet's nanosecond timestamps, ``PARQUET_TYPE_ILLEGAL``); each beside an integer
#: column of the exact nanoseconds since 1970 (``t_ns`` beside ``t``).
TIME = pa.timestamp("us", tz="UTC")
_ROLES = pa.array([role.value for role in ROLE_ORDER])
_OUTCOMES = pa.array(OUTCOMES)
_KINDS = pa.array(list(KINDS))
_PROTOCOLS = pa.array(["modbus", "uss"])
#: Columns of few distinct values, dictionary-encoded in the files (the others, times, indexes,
#: bytes and summaries, would only grow a dictionary to throw away: slower to write, and larger).
DICTIONARY_COLUMNS = ["capture", "slave", "function", "role", "exception_code", "flags", "protocol", "outcome",
                      "kind", "code", "name", "unit", "text", "raw", "value"]
#: The largest dictionary page a column chunk grows before the writer stores the rest of it
#: plain. The values' ``raw`` and ``value`` are few on coils and drives' states and many on
#: registers polled at random: dictionary-encoded up to this size, the ``values`` table of coils
#: and of drives is smaller and faster to write, that of random polling hardly larger (unbounded,
#: much slower). The other dictionaries stay far below it.
DICTIONARY_PAGE_BYTES = 32 << 10
#: Columns written without min/max statistics: texts, bytes and values, whose every row group
#: (a time slice of the whole bus) spans nearly all of them, so that no engine skips one by
#: them, and their statistics would slow the writing of the frames and values tables.
#: Times, indexes, slaves, functions, addresses, exception codes, latencies, roles, kinds,
#: outcomes and the ``crc_ok`` and ``valid`` flags keep theirs.
UNSUMMARISED_COLUMNS = frozenset({"summary", "bytes", "flags", "code", "name", "text", "unit", "raw", "value"})
#: Columns that grow a little from row to row (times, frame indexes), stored as the differences
#: (Parquet's ``DELTA_BINARY_PACKED``, which every engine named above reads): smaller tables,
#: written faster. The values' ``address`` too: a frame's values lie at consecutive addresses
#: (a row per coil), much smaller on coils, a little larger where frames carry a few registers
#: of scattered addresses.
#: But the ``values``' time: a frame's values share its time, and stored plain, zstd takes the
#: repeats (smaller, and faster to write on coils and polling). Those of frames and
#: transactions, a time a row, take differences: half as large and faster.
DELTA_COLUMNS = {table: ["t", "t_ns", "t_end", "t_end_ns", "index", "request_index", "answer_index", "address"]
                 for table in TABLES} | {"values": ["index", "request_index", "address"]}
#: Columns that every row has by construction, declared so (Parquet's ``REQUIRED``): the writer
#: then keeps no definition level per value, and writes faster. Files written before, every
#: column optional, are read together with these (pyarrow datasets, DuckDB). A null
#: in one would be a bug: Arrow refuses to write it, and the export fails rather than store it.
REQUIRED_COLUMNS = {
    "frames": frozenset({"capture", "index", "t", "t_ns", "t_end", "t_end_ns", "role", "crc_ok", "flags", "length",
                         "bytes", "protocol"}),
    "transactions": frozenset({"t", "t_ns", "request_index", "outcome"}),
    "values": frozenset({"t", "t_ns", "index", "slave", "kind", "address", "raw", "valid"}),
    "anomalies": frozenset({"t", "t_ns", "index", "kind"}),
    "latencies": frozenset({"from_ms", "to_ms", "answers"}),
}


def dictionary(codes: npt.NDArray[np.integer], names: pa.Array) -> pa.DictionaryArray:
    """``codes`` (each an index of ``names``, as every caller makes them) as a dictionary column;
    not checked again (a pass over the codes per column)."""
    return pa.DictionaryArray.from_arrays(pa.array(codes.astype(np.int32)), names, safe=False)


def nullable(values: npt.NDArray[np.integer], kind: pa.DataType) -> pa.Array:
    """``values`` with ``NONE`` (-1) as null."""
    return pa.array(values, kind, mask=values == NONE)


def times(name: str, t_ns: npt.NDArray[np.int64]) -> dict[str, pa.Array]:
    """The time column ``name`` (microseconds, rounded down) and ``name_ns`` (exact) of ``t_ns``."""
    return {name: pa.array(t_ns // 1000, TIME), f"{name}_ns": pa.array(t_ns, pa.int64())}


@dataclass
class _Part:
    """One file of the dataset being written: its final name, the partial file, rows held."""

    table: str
    final: Path
    partial: Path
    held: list[pa.RecordBatch] = field(default_factory=list)
    rows: int = 0


class ParquetDataset:
    """Writes one capture's rows into the dataset at ``folder`` (see the module docstring)."""

    def __init__(self, folder: str, bus: str, capture_id: str, metadata: dict[str, str]) -> None:
        self.folder, self.bus, self.capture_id = Path(folder), bus, capture_id
        fault = bus_name_fault(bus)
        if fault is not None:
            raise RtuSniffError(ErrorKind.USAGE, f"bus {bus!r} (the capture file's name): {fault}; give --bus NAME")
        self._refuse_a_capture_held()
        self._refuse_other_times()
        self._metadata = {key.encode(): value.encode() for key, value in metadata.items()}
        self._parts: dict[tuple[str, int], _Part] = {}
        #: Rows written per table.
        self.rows = dict.fromkeys(TABLES, 0)
        #: The files put in place by :meth:`close`, in order.
        self.files: list[Path] = []
        #: Each table's columns, known from its first rows (or an empty batch of them).
        self._schemas: dict[str, pa.Schema] = {}
        self._writer = RowGroupWriter(DICTIONARY_COLUMNS, DELTA_COLUMNS, UNSUMMARISED_COLUMNS, DICTIONARY_PAGE_BYTES)

    def add(self, table: str, t_ns: npt.NDArray[np.int64], columns: dict[str, pa.Array]) -> None:
        """Rows of ``table`` (``t_ns``: each row's time, which chooses its date's file)."""
        batch = _rows(self._schemas, table, columns)
        if not len(t_ns):
            return
        # The first and last day from the least and greatest time: a day for every row is made
        # only for a batch across midnight (a coil batch holds millions of value times).
        first, last = int(t_ns.min()) // DAY_NS, int(t_ns.max()) // DAY_NS
        days = t_ns // DAY_NS if first != last else None
        for day in range(first, last + 1):
            rows = batch if days is None else batch.filter(pa.array(days == day))
            if rows.num_rows:
                self._hold(table, day, rows)
        self.rows[table] += batch.num_rows

    def _hold(self, table: str, day: int, rows: pa.RecordBatch) -> None:
        part = self._parts.get((table, day))
        if part is None:
            part = self._parts[(table, day)] = self._new_part(table, day)
        part.held.append(rows)
        part.rows += rows.num_rows
        if part.rows >= ROW_GROUP_ROWS:
            self._write(part)

    def _refuse_a_capture_held(self) -> None:
        """A capture is in a dataset once, whatever its bus or its file's name: its id (of its
        bytes' SHA-256) names one file per table and day, so any file of that name says it."""
        for held in sorted(self.folder.glob(f"*/bus=*/date=*/{self.capture_id}.parquet"))[:1]:
            bus = held.parent.parent.name.removeprefix("bus=")
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"this capture is in the dataset already, as bus {bus!r} (a "
                                "file of the same capture id: its bytes' SHA-256); a dataset holds a capture once",
                                path=str(held))

    def _refuse_other_times(self) -> None:
        """Files of earlier versions hold nanosecond times: an engine reading both kinds as one table
        fails or mixes units, so they are not mixed."""
        for table in TABLES[:4]:  # those with times
            for held in sorted(self.folder.glob(f"{table}/bus=*/date=*/*.parquet"))[:1]:
                kind = pq.read_schema(held).field("t").type
                if kind != TIME:
                    raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"this dataset's times are {kind} (written by an "
                                        f"earlier rtusniff), this version writes {TIME} with t_ns beside; export into "
                                        "a new folder (or export every capture again)", path=str(held))

    def _new_part(self, table: str, day: int) -> _Part:
        date = np.datetime64(day, "D").astype(str)
        final = self.folder / table / f"bus={self.bus}" / f"date={date}" / f"{self.capture_id}.parquet"
        if final.exists():
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "this capture is in the dataset already (a file of the same "
                                "capture id); a dataset's files are never rewritten", path=str(final))
        final.parent.mkdir(parents=True, exist_ok=True)
        return _Part(table, final, final.with_name(f".{final.name}.partial"))

    def _write(self, part: _Part) -> None:
        """The rows ``part`` holds, handed to the writing thread as one row group."""
        rows = pa.Table.from_batches(part.held).replace_schema_metadata(self._metadata)
        self._writer.write(part.partial, part.table, rows)
        part.held, part.rows = [], 0

    def close(self) -> None:
        """Writes what is held and puts every file in place (``files``). A table the capture has
        no row for gets a file without rows on its first day: every table of a dataset can be
        read, whatever captures it holds."""
        try:
            self._write_all()
        except BaseException:
            self.abandon()  # a failure in the last writes (a full disk): nothing of it in the dataset
            raise
        for part in self._parts.values():
            try:
                os.link(part.partial, part.final)  # never over a file that appeared meanwhile
            except FileExistsError:
                raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "appeared while exporting (the same capture exported "
                                    "twice at once?); left as it is", path=str(part.final)) from None
            finally:
                part.partial.unlink()
        self.files = sorted(part.final for part in self._parts.values())

    def _write_all(self) -> None:
        """Every row held, written, and every file closed."""
        days = sorted({day for _, day in self._parts})
        for table, schema in self._schemas.items():
            if days and not any(name == table for name, _ in self._parts):
                self._hold(table, days[0], pa.RecordBatch.from_pylist([], schema))
        for part in self._parts.values():
            if part.held:
                self._write(part)
        self._writer.close()

    def abandon(self) -> None:
        """A failed export: no file of it is left in the dataset."""
        self._writer.abandon()  # its files closed, no write under way
        for part in self._parts.values():
            with contextlib.suppress(OSError):
                part.partial.unlink()


class ArrowTables:
    """The dataset's tables of one capture held in memory as Arrow tables, for the library
    (:mod:`sniffer.library`): what :class:`ParquetDataset` writes into files, row for row, with
    the files' schema and key-value metadata, and each row's day (its ``date`` partition);
    nothing on disk."""

    def __init__(self, bus: str, metadata: dict[str, str]) -> None:
        self.bus = bus
        self._metadata = {key.encode(): value.encode() for key, value in metadata.items()}
        self._batches: dict[str, list[pa.RecordBatch]] = {}
        self._days: dict[str, list[npt.NDArray[np.int64]]] = {}
        self._schemas: dict[str, pa.Schema] = {}
        self.files: list[Path] = []  # none: a dataset's interface
        #: Each table, once closed, and each of its rows' day (days since 1970, UTC).
        self.tables: dict[str, pa.Table] = {}
        self.days: dict[str, npt.NDArray[np.int64]] = {}

    def add(self, table: str, t_ns: npt.NDArray[np.int64], columns: dict[str, pa.Array]) -> None:
        """Rows of ``table``, as :meth:`ParquetDataset.add` takes them."""
        rows = _rows(self._schemas, table, columns)
        if rows.num_rows:
            self._batches.setdefault(table, []).append(rows)
            self._days.setdefault(table, []).append(t_ns // DAY_NS)

    def close(self) -> None:
        self.tables = {table: pa.Table.from_batches(self._batches.get(table, []), schema).replace_schema_metadata(
            self._metadata) for table, schema in self._schemas.items()}
        self.days = {table: np.concatenate(self._days.get(table) or [np.zeros(0, np.int64)])
                     for table in self._schemas}

    def abandon(self) -> None:
        self._batches.clear()


def _rows(schemas: dict[str, pa.Schema], table: str, columns: dict[str, pa.Array]) -> pa.RecordBatch:
    """``columns`` as rows of ``table``, whose schema its first rows set (kept in ``schemas``)."""
    schema = schemas.get(table)
    if schema is None:
        schema = schemas[table] = _schema(table, columns)
    return pa.RecordBatch.from_arrays(list(columns.values()), schema=schema)


def _schema(table: str, columns: dict[str, pa.Array]) -> pa.Schema:
    """The table's schema from its first columns: those of :data:`REQUIRED_COLUMNS` not null."""
    required = REQUIRED_COLUMNS[table]
    return pa.schema([pa.field(name, column.type, nullable=name not in required) for name, column in columns.items()])


@functools.lru_cache(maxsize=64)
def _one_text(text: str) -> pa.Array:
    """``text`` as a column of one (made once, not for each batch's dictionary)."""
    return pa.array([text], pa.string())


def frame_columns(batch: AnnotatedBatch, positions: npt.NDArray[np.int64], capture: str,
                  summaries: Summaries) -> dict[str, pa.Array]:
    """The ``frames`` table's columns of the messages at ``positions`` (``summaries``: their
    batch's, :func:`~sniffer.exports.parquet_summaries.summaries`)."""
    messages, frames = batch.messages, batch.messages.frames
    every = len(positions) == len(messages)  # every message, in order: the columns as they are

    def at(column: npt.NDArray[Any]) -> npt.NDArray[Any]:
        return column if every else column[positions]

    offsets = frames.offsets
    starts, ends = at(offsets[:-1]), at(offsets[1:])
    raw = _binary(frames.data, starts, ends)
    flag_lists = _flag_lists(at(messages.flags))
    latency = at(messages.latency_ns)
    columns = {
        "capture": dictionary(np.zeros(len(positions), np.int32), _one_text(capture)),
        "index": pa.array(positions + frames.first_index, pa.int64()),
        **times("t", at(frames.t_start_ns)),
        **times("t_end", at(frames.t_end_ns)),
        "slave": nullable(at(messages.slave), pa.int16()),
        "function": nullable(at(messages.function), pa.int16()),
        "role": dictionary(at(messages.role), _ROLES),
        "crc_ok": pa.array(at(frames.crc_ok), pa.bool_()),
        "exception_code": nullable(at(messages.exception_code), pa.int16()),
        "flags": flag_lists,
        "request_index": nullable(at(messages.request_index), pa.int64()),
        "latency_ms": pa.array(latency / 1e6, pa.float64(), mask=latency == NONE),
        "length": pa.array((ends - starts).astype(np.int32), pa.int32()),
        "bytes": raw,
        "summary": summaries.of(None if every else positions),
        "protocol": dictionary(at(frames.protocols()), _PROTOCOLS),
    }
    return columns


def _flag_lists(flags: npt.NDArray[np.integer]) -> pa.ListArray:
    """Each frame's flags as a list of their names: the names of each distinct set of flags
    repeated by numpy, the list column made from its offsets."""
    masks, which = _distinct_masks(flags)
    names = [flag_names_of(int(mask)) for mask in masks.tolist()]
    sizes = np.array([len(each) for each in names], np.int64)
    firsts = np.cumsum(sizes) - sizes
    lengths = sizes[which]
    offsets = np.zeros(len(lengths) + 1, np.int32)
    np.cumsum(lengths, out=offsets[1:])
    every_name = np.array([name for each in names for name in each] or [""], object)
    taken = every_name[spread(firsts[which], lengths)]
    return pa.ListArray.from_arrays(pa.array(offsets, pa.int32()), pa.array(taken.tolist(), pa.string()))


def transaction_columns(values: dict[str, npt.NDArray[np.int64]]) -> dict[str, pa.Array]:
    """The ``transactions`` table's columns from :meth:`TransactionEncoder.columns`."""
    latency = values["latency_ns"]
    return {
        **times("t", values["t_ns"]),
        "request_index": pa.array(values["request_index"], pa.int64()),
        "answer_index": nullable(values["answer_index"], pa.int64()),
        "slave": nullable(values["slave"], pa.int16()),
        "function": nullable(values["function"], pa.int16()),
        "outcome": dictionary(values["outcome"], _OUTCOMES),
        "exception_code": nullable(values["exception_code"], pa.int16()),
        "latency_ms": pa.array(latency / 1e6, pa.float64(), mask=latency == NONE),
    }


def anomaly_columns(batch: AnnotatedBatch, positions: npt.NDArray[np.int64], summaries: Summaries) -> tuple[
        npt.NDArray[np.int64], dict[str, pa.Array]]:
    """The ``anomalies`` table: a row per kind each message at ``positions`` shows, in frame order
    (``summaries``: their batch's)."""
    messages, frames = batch.messages, batch.messages.frames
    masks = anomaly_masks(messages)
    # The few messages showing any, first: each kind then picks from them, not from the batch.
    showing = positions[np.logical_or.reduce(list(masks.values()))[positions]]
    rows, kinds = [], []
    for kind_index, mask in enumerate(masks.values()):
        found = showing[mask[showing]]
        rows.append(found)
        kinds.append(np.full(len(found), kind_index, np.int32))
    row, kind = np.concatenate(rows), np.concatenate(kinds)
    order = np.lexsort((kind, row))
    row, kind = row[order], kind[order]
    t_ns = frames.t_start_ns[row]
    return t_ns, {
        **times("t", t_ns),
        "index": pa.array(row + frames.first_index, pa.int64()),
        "slave": nullable(messages.slave[row], pa.int16()),
        "function": nullable(messages.function[row], pa.int16()),
        "kind": dictionary(kind, _KINDS),
        "exception_code": nullable(messages.exception_code[row], pa.int16()),
        "summary": summaries.of(row),
    }


def _distinct_masks(flags: npt.NDArray[np.integer]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The distinct sets of flags, in order, and each frame's place among them: counted by
    ``bincount`` and looked up (``np.unique`` would sort the batch)."""
    present = np.flatnonzero(np.bincount(flags)) if len(flags) else np.zeros(0, np.int64)
    place = np.zeros(int(present[-1]) + 1 if len(present) else 0, np.int64)
    place[present] = np.arange(len(present))
    return present, place[flags]


def _binary(data: bytes, starts: npt.NDArray[np.int64], ends: npt.NDArray[np.int64]) -> pa.Array:
    """The byte strings ``data[starts[i]:ends[i]]`` as one binary column, without a Python loop."""
    lengths = ends - starts
    offsets = np.zeros(len(starts) + 1, np.int32)
    np.cumsum(lengths, out=offsets[1:])
    if len(starts) and (np.diff(starts) == lengths[:-1]).all():
        body = data[int(starts[0]) : int(ends[-1])]  # contiguous: every frame of the batch
    else:
        raw = np.frombuffer(data, np.uint8)
        body = raw[spread(starts, lengths)].tobytes()
    return pa.Array.from_buffers(pa.binary(), len(starts), [None, pa.py_buffer(offsets), pa.py_buffer(body)])
