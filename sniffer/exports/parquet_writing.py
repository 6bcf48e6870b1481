"""Parquet row groups written by a thread of their own, which alone touches the writers.

pyarrow lets go of the GIL while it compresses, so the next rows are decoded meanwhile. The
thread creates, writes and closes every ``pq.ParquetWriter``; the decoding thread only hands it
work through a queue of at most ``QUEUED_WRITES`` row groups. That is also what makes a stop
safe: Ctrl-C and SIGTERM raise wherever the decoding thread happens to be (inside ``queue.put``
or ``Thread.start`` too), and a writer closed by one thread while another writes to it crashes
the process (seen here: a segmentation fault, when the executor used before had not yet counted
its thread). A stop is one more item in the queue, after which the thread closes its writers and
ends, and the caller waits for it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Mapping
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

#: Row groups handed to the writing thread and not written yet, at most.
QUEUED_WRITES = 2
_CLOSE, _ABANDON = "close", "abandon"


class RowGroupWriter:
    """Writes row groups to their files, in the order handed over, in a thread of its own."""

    def __init__(self, dictionary_columns: list[str], delta_columns: Mapping[str, list[str]],
                 unsummarised_columns: frozenset[str], dictionary_page_bytes: int) -> None:
        """``dictionary_columns``: the columns dictionary-encoded (those of few distinct values;
        trying it on the others costs time and bytes), each up to a dictionary page of
        ``dictionary_page_bytes`` a row group (then plain); ``delta_columns``: by table, the
        integer columns stored as differences; ``unsummarised_columns``: those
        written without min/max statistics."""
        self._dictionary_columns = dictionary_columns
        self._delta_columns = delta_columns
        self._unsummarised = unsummarised_columns
        self._dictionary_page_bytes = dictionary_page_bytes
        self._queue: queue.Queue[tuple[Path, str, pa.Table] | str] = queue.Queue(QUEUED_WRITES)
        self._writers: dict[Path, pq.ParquetWriter] = {}
        #: The first failure of the thread (a full disk); the thread then drops what comes.
        self.failure: Exception | None = None
        # A daemon: were the caller stopped by a second signal before it waited for the thread,
        # the interpreter would not wait for it either.
        self._thread = threading.Thread(target=self._run, name="rtusniff-parquet", daemon=True)
        self._thread.start()

    def write(self, path: Path, name: str, table: pa.Table) -> None:
        """``table`` (rows of the table ``name``) as the next row group of ``path`` (created
        with its schema at the first); an earlier write's failure is raised here."""
        self._raise_failure()
        self._queue.put((path, name, table))

    def close(self) -> None:
        """Every row group written and every file closed; a failure is raised."""
        self._queue.put(_CLOSE)
        self._thread.join()
        self._raise_failure()

    def abandon(self) -> None:
        """No more writes: the thread closes its files and ends, and is waited for (the caller
        may then remove the files)."""
        if self._thread.is_alive():
            self._queue.put(_ABANDON)
            self._thread.join()

    def _raise_failure(self) -> None:
        if self.failure is not None:
            raise self.failure

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if isinstance(item, str):
                self._close_writers()
                return
            if self.failure is not None:
                continue  # drained, so that the caller never waits on a full queue
            path, name, table = item
            try:
                writer = self._writers.get(path)
                if writer is None:
                    writer = self._writers[path] = self._writer(path, name, table.schema)
                writer.write_table(table)
            except Exception as exc:  # an OSError mostly: told to the caller at its next call
                self.failure = exc

    def _writer(self, path: Path, name: str, schema: pa.Schema) -> pq.ParquetWriter:
        delta = {column: "DELTA_BINARY_PACKED" for column in self._delta_columns.get(name, ())
                 if column in schema.names}
        summarised = [name for name in schema.names if name not in self._unsummarised]
        return pq.ParquetWriter(path, schema, compression="zstd", use_dictionary=self._dictionary_columns,
                                column_encoding=delta or None, write_statistics=summarised,
                                dictionary_pagesize_limit=self._dictionary_page_bytes)

    def _close_writers(self) -> None:
        for writer in self._writers.values():
            try:
                writer.close()
            except Exception as exc:  # the last bytes of a file, on a full disk
                self.failure = self.failure or exc
