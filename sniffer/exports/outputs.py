"""The export outputs as sinks (:mod:`sniffer.sinks`): MCAP, Rerun, pcap.

This module stays light: each sink imports its exporter's library when the export
starts (MCAP and zstandard would slow every command's start-up, Rerun much more), and
exporters that start threads (Rerun's SDK, the MCAP writer's
compressor) are made in ``start``, after the decoding process is forked: a fork
copies no thread, only the locks they hold.
"""

from __future__ import annotations

import argparse
import hashlib
import shlex
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.message import MessageBatch
from decoders.stats import Statistics
from sniffer.exports.latency_bins import latency_bins
from sniffer.exports.pcap_export import PcapExporter
from sniffer.exports.transactions import TransactionEncoder
from sniffer.pipeline import Analysis
from sniffer.sinks import FileSink
from sniffer.tool_version import tool_version

if TYPE_CHECKING:
    from sniffer.exports.mcap_export import (
        McapExporter,  # noqa: F401 - named in a string (imported when used)
        Prepared,
    )
    from sniffer.exports.parquet_export import (  # noqa: F401 - named in a string (imported when used)
        ArrowTables,
        ParquetDataset,
    )
    from sniffer.exports.parquet_values import NumericValues
    from sniffer.exports.rerun_export import RerunExporter  # noqa: F401 - named in a string (imported when used)


class McapSink(FileSink["McapExporter"]):
    """Decoded MCAP: raw chunks, frames, transactions (prepared where frames are paired),
    parameter values, a log."""

    wants_chunks = True
    wants_messages = True

    def __init__(self, path: str, args: argparse.Namespace, analysis: Analysis) -> None:
        super().__init__(path)
        self._args, self._analysis = args, analysis
        from sniffer.exports.mcap_export import preparer  # noqa: PLC0415 - only for an MCAP export

        #: A batch's transactions and its frame records' own fields (need no decodings).
        self.prepare = preparer()
        self._kept: AnnotatedBatch | None = None

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        from sniffer.exports.mcap_export import McapExporter  # noqa: PLC0415 - only for an MCAP export

        with self.writing():
            self.exporter = McapExporter(self.path or "", info, line, _metadata(self._args, self._analysis))

    def chunks(self, batch: ChunkBatch) -> None:
        if self.exporter is not None:
            with self.writing():
                self.exporter.raw(batch)

    def messages(self, batch: AnnotatedBatch) -> None:
        self._kept = batch  # written with what was prepared for it

    def prepared(self, value: Prepared) -> None:
        batch, self._kept = self._kept, None
        if self.exporter is not None:
            with self.writing():
                if batch is not None:
                    self.exporter.messages(batch, value.fields)
                    self.frames_written += len(batch.messages)
                self.exporter.transactions(value.transactions, value.t_ns)

    def interrupted(self) -> None:
        """A metadata record says the file is incomplete, and how many frames it holds."""
        if self.exporter is not None:
            with self.writing():
                self.exporter.incomplete(self.frames_written)


class RerunSink(FileSink["RerunExporter"]):
    """A Rerun recording (``path``); a viewer too: :class:`sniffer.exports.streams.RerunStreamSink`."""

    wants_messages = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        from sniffer.exports.rerun_export import RerunExporter  # noqa: PLC0415 - a third of a second to import

        with self.writing():
            self.exporter = RerunExporter(self.path)

    def messages(self, batch: AnnotatedBatch) -> None:
        self.frames_written += len(batch.messages)
        if self.exporter is not None:
            with self.writing():
                self.exporter.messages(batch)


class ParquetSink(FileSink["ParquetDataset | ArrowTables"]):
    """Decoded tables added to a Parquet dataset (:mod:`sniffer.exports.parquet_export`), or
    held in memory as Arrow tables (``folder`` ``None``: :attr:`tables`, for the library)."""

    wants_messages = True
    joins_batches = True

    def __init__(self, folder: str | None, args: argparse.Namespace, analysis: Analysis) -> None:
        super().__init__(folder)
        self._args, self._analysis = args, analysis
        #: The tables, when held in memory (filled once closed).
        self.tables: ArrowTables | None = None
        self._finished = False
        self.files: list[str] = []
        encoder = TransactionEncoder()
        self.prepare = lambda batch: _with_latency_bins(encoder.columns(batch, np.arange(len(batch))))

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        from sniffer.exports.parquet_export import ArrowTables, ParquetDataset  # noqa: PLC0415 - pyarrow
        from sniffer.exports.parquet_latencies import LatencyHistograms  # noqa: PLC0415 - pyarrow
        from sniffer.exports.parquet_values import ValueCollector  # noqa: PLC0415 - pyarrow

        metadata = _metadata(self._args, self._analysis)
        metadata |= {"line": line.format(), "timing": info.timing.value, "tool": tool_version()}
        capture_id = hashlib.sha256(metadata["source_sha256"].encode()).hexdigest()[:16]
        bus = self._args.bus or Path(self._args.capture[0]).stem
        self._values = ValueCollector()
        self._latencies = LatencyHistograms()
        kept = {f"rtusniff.{k}": v for k, v in metadata.items()}
        if self.path is None:
            self.exporter = self.tables = ArrowTables(bus, kept)
            return
        with self.writing():
            self.exporter = ParquetDataset(self.path, bus, capture_id, kept)

    def messages(self, batch: AnnotatedBatch) -> None:
        from sniffer.exports.parquet_export import anomaly_columns, frame_columns  # noqa: PLC0415
        from sniffer.exports.parquet_summaries import summaries  # noqa: PLC0415 - pyarrow
        from sniffer.exports.parquet_values import columnar_values  # noqa: PLC0415 - loaded already

        self.frames_written += len(batch.messages)
        if self.exporter is None:
            return
        positions = np.asarray(batch.positions(), np.int64)
        frames, texts = batch.messages.frames, summaries(batch)
        with self.writing():
            self.exporter.add("frames", frames.t_start_ns[positions],
                              frame_columns(batch, positions, self._source, texts))
            self.exporter.add("anomalies", *anomaly_columns(batch, positions, texts))
            self._values.messages(batch)
            self._add_values(columnar_values(batch))

    @property
    def _source(self) -> str:
        return " + ".join(self._args.capture)

    def _add_values(self, columnar: NumericValues | None = None) -> None:
        from sniffer.exports.parquet_value_columns import value_columns  # noqa: PLC0415 - pyarrow

        rows = self._values.take()
        if (rows or (columnar is not None and len(columnar))) and self.exporter is not None:
            self.exporter.add("values", *value_columns(rows, columnar))

    def prepared(self, value: dict[str, npt.NDArray[np.int64]]) -> None:
        from sniffer.exports.parquet_export import transaction_columns  # noqa: PLC0415 - loaded already

        if self.exporter is not None:
            with self.writing():
                self.exporter.add("transactions", value["t_ns"], transaction_columns(value))
            self._latencies.add(value["latency_bins"], value["latency_counts"])

    def finish(self, statistics: Statistics) -> None:
        from sniffer.exports.parquet_value_columns import value_columns  # noqa: PLC0415 - pyarrow
        from sniffer.exports.parquet_values import CollectedValues  # noqa: PLC0415 - loaded already

        with self.writing():
            self._values.finish(statistics)
            self._add_values()
            if self.exporter is not None:
                self.exporter.add("values", *value_columns(CollectedValues()))  # the table's columns, had it no row
                self.exporter.add("latencies", *self._latencies.columns())
        self._finished = True

    def close(self) -> None:
        exporter, self.exporter = self.exporter, None
        if exporter is None:
            return
        if not self._finished:
            exporter.abandon()  # a failed or interrupted export adds nothing to the dataset
            return
        with self.writing():
            exporter.close()
        self.files = [str(path) for path in exporter.files]


class PcapSink(FileSink[PcapExporter]):
    """pcap for Wireshark: a classic pcap needs no decoding, so it takes the framed batches;
    pcapng's comments say each frame's summary, so it takes the annotated ones."""

    def __init__(self, path: str, *, udp: bool = True, pcapng: bool | None = None) -> None:
        super().__init__(path)
        #: The pipe written to has no reader any more (Wireshark stopped capturing): nothing more
        #: is written, and a live capture ends.
        self.reader_gone = False
        with self.writing():
            self.exporter = PcapExporter(path, udp=udp, pcapng=pcapng)
        self.wants_messages = self.exporter.comments
        self.wants_frames = not self.wants_messages

    def frames(self, batch: MessageBatch) -> None:
        self._write(batch, None)

    def messages(self, batch: AnnotatedBatch) -> None:
        assert batch.rows is None, "a pcap holds every frame delivered: nothing filters them"
        self._write(batch.messages, batch.summaries())

    def _write(self, batch: MessageBatch, lines: list[str] | None) -> None:
        self.frames_written += len(batch)
        if self.exporter is not None:
            with self.writing(), self._reader_may_leave():
                self.exporter.batch(batch, lines)

    def close(self) -> None:
        exporter, self.exporter = self.exporter, None
        if exporter is not None:
            with self.writing(), self._reader_may_leave():
                exporter.close()

    @contextmanager
    def _reader_may_leave(self) -> Iterator[None]:
        """A pipe whose reader closed it (Wireshark stopped capturing) is no failure: caught before
        :meth:`writing` makes it one, it ends the writing."""
        try:
            yield
        except BrokenPipeError:
            self.reader_gone, self.exporter = True, None


def _with_latency_bins(transactions: dict[str, npt.NDArray[np.int64]]) -> dict[str, npt.NDArray[np.int64]]:
    """A batch's transactions with the bins their answers' latencies fall in and how many in each
    (``latency_bins``, ``latency_counts``): binned in the decoding process (see
    :mod:`sniffer.exports.latency_bins`)."""
    transactions["latency_bins"], transactions["latency_counts"] = latency_bins(transactions)
    return transactions


def _metadata(args: argparse.Namespace, analysis: Analysis) -> dict[str, str]:
    book = analysis.profiles
    profiles = "generic" if book is None else ", ".join(
        [f"default {book.default.id}", *(f"slave {s}: {p.id}" for s, p in sorted(book.per_slave.items()))]
    )
    return {
        "source": " + ".join(args.capture),
        # One digest per file, in the order named (a rotated recording: every part).
        "source_sha256": " ".join(sha256_of(path) for path in args.capture),
        "command": shlex.join(args.command_line),
        "profiles": profiles,
    }


def sha256_of(path: str) -> str:
    """The SHA-256 of a file, in hex (``-``: standard input, which cannot be read twice)."""
    if path == "-":
        return "(standard input)"
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
