"""Decoding on Spark: captures decoded inside the executors, their tables as Spark DataFrames.

    tables = sniffer.spark.decode(spark, "s3://plant/captures/", profile="atv71")
    tables["transactions"].write.partitionBy("bus", "date").parquet("s3://plant/dataset/transactions")

An ordinary Spark job, no scheduler of ours: Spark reads each capture whole as a binary file
(``binaryFile``: local, HDFS or object-store paths, a folder, a glob), and one Arrow function
(``mapInArrow``) decodes it inside an executor with :func:`sniffer.library.open_capture`, the
options given here shipped with the function (profile files read here, on the driver, and
carried as their text). Each capture becomes one row per table holding that table as Arrow IPC,
kept (``persist``) so that each capture is decoded once whichever tables are read; each table is
then those rows read back by a second Arrow function into its columns. A table's rows are the
ones ``export --parquet`` writes for that capture, with the dataset's partition columns ``bus``
and ``date`` last, and ``capture`` the file's path as Spark names it; dictionary columns are
plain strings (Spark has no dictionary type). A capture that cannot be decoded is a row of the
``errors`` table (its path, exit code and the command line's error line), never a failed job.

The executors' Python needs rtusniff (``pip install rtusniff``; ``PYSPARK_PYTHON``). A capture
is read whole into an executor's memory (Spark's binary files stop at 2 GB): record a plant in
files of an hour or a day (``capture --rotate``).
"""

from __future__ import annotations

import functools
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote, urlparse

import pyarrow as pa

from decoders.crc import crc_bytes
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports import TABLES
from sniffer.library import open_capture
from sniffer.profiles_io import profile_file_text

if TYPE_CHECKING:
    from pyspark.sql import DataFrame, SparkSession

#: What the decoding function makes of each capture: a row per table (its Arrow IPC stream), or
#: one ``errors`` row.
_DECODED = "path string, table string, ipc binary, exit_code int, error string"
#: The table of captures that could not be decoded.
ERRORS = "errors"


def decode(spark: SparkSession, paths: str | Sequence[str], **options: Any) -> dict[str, DataFrame]:
    """The tables of the captures at ``paths`` (files, folders, globs Spark reads), decoded in
    the executors with ``options`` (those of :func:`~sniffer.library.open_capture`), by name:
    each of :data:`~sniffer.exports.TABLES` and :data:`ERRORS`. The decoded captures stay in
    Spark's cache while the tables are read (``spark.catalog.clearCache()`` lets them go)."""
    from pyspark.sql.pandas.types import from_arrow_schema  # noqa: PLC0415 - pyspark, only here

    shipped = _shipped(options)
    files = spark.read.format("binaryFile").load(list(paths) if not isinstance(paths, str) else paths)
    decoded = files.select("path", "content").mapInArrow(functools.partial(_decode_files, shipped), _DECODED)
    decoded = decoded.persist()
    tables = {}
    for name, schema in table_schemas().items():
        rows = decoded.where(decoded.table == name).select("ipc")
        tables[name] = rows.mapInArrow(functools.partial(_table_rows, schema),
                                       from_arrow_schema(schema, prefer_timestamp_ntz=False))
    tables[ERRORS] = decoded.where(decoded.table == ERRORS).select("path", "exit_code", "error")
    return tables


def _shipped(options: dict[str, Any]) -> dict[str, Any]:
    """``options`` as the executors get them: each profile file's name and text instead of its path."""
    files = options.get("profile_file") or []
    named = [(Path(path).name, profile_file_text(str(path))) for path in ([files] if isinstance(files, str) else files)]
    return {**options, "profile_file": named}


def _decode_files(shipped: dict[str, Any], batches: Iterable[pa.RecordBatch]) -> Iterator[pa.RecordBatch]:
    """In an executor: each capture of ``batches`` (``path``, ``content``) decoded."""
    for batch in batches:
        for uri, content in zip(batch.column("path").to_pylist(), batch.column("content").to_pylist(), strict=True):
            yield decoded_capture(uri, content, shipped)


def decoded_capture(uri: str, content: bytes, shipped: dict[str, Any]) -> pa.RecordBatch:
    """One capture's tables as rows of :data:`_DECODED`: decoded from a file of its own name in a
    folder of its own (a format is known by its suffix or first bytes), which is removed after."""
    name = PurePosixPath(unquote(urlparse(uri).path)).name or "capture"
    with tempfile.TemporaryDirectory(prefix="rtusniff-") as folder:
        local = Path(folder) / name
        local.write_bytes(content)
        profiles = []
        for count, (profile_name, text) in enumerate(shipped["profile_file"]):
            profile = Path(folder) / f"profile-{count}" / profile_name
            profile.parent.mkdir()
            profile.write_text(text, encoding="utf-8")
            profiles.append(str(profile))
        options = {"bus": Path(name).stem, **shipped, "profile_file": profiles}
        try:
            capture = open_capture(local, **options)
            tables = {table: _plain(capture.table(table, partitions=True), uri) for table in TABLES}
        except RtuSniffError as error:  # said as the command line says it, of the file Spark names
            said = RtuSniffError(error.kind, error.message, path=uri if error.path == str(local) else error.path,
                                 location=error.location)
            return _error_row(uri, error.kind.exit_code, f"error: {said}")
        except Exception as error:  # any other failure is this capture's, not the job's
            return _error_row(uri, ErrorKind.RUNTIME.exit_code, f"error: {uri}: {type(error).__name__}: {error}")
    streams = [_ipc(table) for table in tables.values()]
    return pa.RecordBatch.from_pydict({"path": [uri] * len(tables), "table": list(tables), "ipc": streams,
                                       "exit_code": pa.nulls(len(tables), pa.int32()),
                                       "error": pa.nulls(len(tables), pa.string())})


def _error_row(uri: str, code: int, line: str) -> pa.RecordBatch:
    return pa.RecordBatch.from_pydict({"path": [uri], "table": [ERRORS], "ipc": pa.nulls(1, pa.binary()),
                                       "exit_code": pa.array([code], pa.int32()), "error": [line]})


def _plain(table: pa.Table, uri: str) -> pa.Table:
    """``table`` as Spark takes it: dictionary columns decoded, ``capture`` the file's path."""
    columns = [pa.chunked_array([pa.array([uri] * len(table), pa.string())]) if field.name == "capture"
               else column.cast(field.type.value_type) if pa.types.is_dictionary(field.type) else column
               for field, column in zip(table.schema, table.columns, strict=True)]
    fields = [pa.field(field.name, column.type, field.nullable) for field, column in
              zip(table.schema, columns, strict=True)]
    return pa.Table.from_arrays(columns, schema=pa.schema(fields))


def _ipc(table: pa.Table) -> bytes:
    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, table.schema) as writer:
        writer.write_table(table)
    return bytes(sink.getvalue().to_pybytes())


def _table_rows(schema: pa.Schema, batches: Iterable[pa.RecordBatch]) -> Iterator[pa.RecordBatch]:
    """In an executor: a table's rows, read back from each capture's IPC stream."""
    for batch in batches:
        for stream in batch.column("ipc").to_pylist():
            for rows in pa.ipc.open_stream(stream):
                yield rows.cast(schema)


@functools.cache
def table_schemas() -> dict[str, pa.Schema]:
    """Each table's schema as the executors make it: learnt from a capture of one exchange
    decoded here (the tables' columns do not depend on the traffic)."""
    request, answer = bytes.fromhex("010300000001"), bytes.fromhex("0103020000")
    text = ("# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n"
            f"1700000000.000000000 {(request + crc_bytes(request)).hex()}\n"
            f"1700000000.010000000 {(answer + crc_bytes(answer)).hex()}\n")
    batch = decoded_capture("schema.log", text.encode(), _shipped({}))
    streams = dict(zip(batch.column("table").to_pylist(), batch.column("ipc").to_pylist(), strict=True))
    return {table: pa.ipc.open_stream(streams[table]).schema for table in TABLES}
