"""The ``--format jsonl`` view: one JSON object per line."""

from __future__ import annotations

import os
from typing import Any, BinaryIO, TextIO

from decoders.capture import CaptureInfo
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.stats import SkippedReads, Statistics
from sniffer.encoding.frame_fields import FrameFields, frame_fields
from sniffer.encoding.param_text import encode_record
from sniffer.encoding.records import (
    FrameRecordEncoder,
    capture_record,
    device_record,
)
from sniffer.encoding.rows import Rows
from sniffer.sinks import Sink


class JsonlView(Sink):
    """Writes a ``capture`` record, then one ``frame`` record per message. What a record says
    that no decoding says (index, times, flags, pairing, latency) is laid out by ``prepare``,
    where frames are paired: in the decoding process with ``--jobs 2``."""

    def __init__(self, out: TextIO) -> None:
        self._out = out
        self._frames = FrameRecordEncoder()
        self._bytes_out = utf8_bytes_under(out)
        self._kept: AnnotatedBatch | None = None
        self.prepare = frame_fields
        #: Frame records written.
        self.shown = 0

    wants_messages = True
    wants_statistics = True

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self._frames.channels = info.channels
        self._write(capture_record(source, info, line))

    def messages(self, batch: AnnotatedBatch) -> None:
        self._kept = batch  # frames in columns are spelt from their columns

    def prepared(self, value: FrameFields) -> None:
        """Writes the batch kept by :meth:`messages`, with the fields its frames' records take
        from no decoding, made by ``prepare`` where the frames were paired."""
        batch, self._kept = self._kept, None
        if batch is None:
            return
        self.shown += len(batch)
        rows = self._frames.rows(batch, end=b"\n", fields=value)
        if any(decoding.device is not None for decoding in batch.decoded):  # none in columns
            self._write_with_devices(rows, batch)
        else:
            self._write_rows(rows.data)

    def _write_rows(self, data: bytes | bytearray) -> None:
        """Records built as UTF-8 bytes, written as they are where the text stream would only
        encode them again (megabytes a second of coil records)."""
        if self._bytes_out is None:
            self._out.write(data.decode())
            return
        self._out.flush()  # what the text layer holds goes first
        self._bytes_out.write(data)

    def gap(self, skipped: SkippedReads) -> None:
        """A ``gap`` record where a live capture skipped reads: what lies between the frames
        around it was not decoded (the recording has it)."""
        self._write({"kind": "gap", "t": skipped.t_ns / 1e9, "t_ns": skipped.t_ns, "reads": skipped.reads,
                     "bytes": skipped.size})

    def finish(self, statistics: Statistics) -> None:
        """The closing ``summary`` record: statistics of every frame, filtered or not."""
        self._write({"kind": "summary", **statistics.to_dict()})
        self._out.flush()

    def _write(self, record: dict[str, Any]) -> None:
        self._out.write(encode_record(record) + "\n")

    def _write_with_devices(self, rows: Rows, batch: AnnotatedBatch) -> None:
        """The frame records, each followed by its ``device`` record (a slave identified itself)."""
        first, decodings, written = batch.messages.frames.first_index, batch.decoded, 0
        for row, position in enumerate(batch.positions()):
            device = decodings[position].device
            if device is not None:
                end = int(rows.offsets[row + 1])
                self._write_rows(rows.data[written:end])
                self._write(device_record(first + position, device))
                written = end
        self._write_rows(rows.data[written:])


def utf8_bytes_under(out: TextIO) -> BinaryIO | None:
    """The byte stream under ``out`` when writing to it directly writes what ``out`` would:
    UTF-8 and no newline translation (not on Windows, where text streams write ``\r\n``)."""
    encoding = (getattr(out, "encoding", None) or "").lower().replace("-", "").replace("_", "")
    buffer: BinaryIO | None = getattr(out, "buffer", None)
    return buffer if encoding == "utf8" and os.linesep == "\n" else None
