"""Decoded MCAP for Foxglove: raw chunks, frames, transactions, parameter values, a log.

Channels (JSON Schema, JSON messages; the schemas are below and in the README):

* ``/rtusniff/raw_chunks``: the capture itself, as the native capture format writes it,
  with its ``rtusniff.capture`` metadata: an exported file is also a capture.
* ``/modbus/frames``: every frame record of the JSONL output.
* ``/modbus/transactions``: request, answer, latency, outcome (answered, exception,
  crc_error, timeout, broadcast).
* ``/slave/N/params``: one message per answer or write, the numeric values by code
  (``RFRD``, ``HSP``) or address: Foxglove's Plot panel charts ``/slave/2/params.RFRD``.
* ``/modbus/log``: ``foxglove.Log`` in protobuf (which Foxglove's Log panel and Rerun both
  render) per frame, level ERROR for CRC errors, timeouts, exceptions, WARNING for gap_1_5,
  short_idle, retries, unexpected answers, noise.

Metadata ``rtusniff.export``: line, timing, source file and SHA-256, tool version, command
line, profiles. Written by :mod:`sniffer.exports.mcap_writer` a block of messages at a time:
zstd chunks, message indexes, a summary section with its indexes. Each channel's messages of a
batch are built as columns (:mod:`sniffer.encoding.rows`) and written as one block; what a decoding
determines (log text, numeric params, the frame record's fixed parts) is built once per decoding.
Numbers are spelt for speed, not as ``json.dumps`` spells them: times as the exact decimals of
their nanoseconds (``"t":1700000000.001997592``), a frame's and a transaction's own fields padded
with spaces to one width per batch (:mod:`sniffer.encoding.blocks`).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable
from typing import Any, BinaryIO, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.decoded_batch import AnnotatedBatch
from decoders.distinct import distinct
from decoders.line import LineSettings
from decoders.message import NONE, MessageBatch
from sniffer.encoding.decoded_texts import FrameTexts, each_message
from sniffer.encoding.frame_fields import BlockFields, block_fields
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.encoding.rows import Column, Integers, Rows, Table, join_rows, number_texts
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports import foxglove_log
from sniffer.exports.levels import FLAG_SUFFIXES, log_levels
from sniffer.exports.mcap_writer import HEADER_SIZE, ColumnarMcapWriter, MessageBlock
from sniffer.exports.published import PublishedValues
from sniffer.exports.transactions import OUTCOMES, TransactionEncoder
from sniffer.io.mcap_blocks import (
    LAYOUT_DOC,
    MESSAGE_ENCODING,
    METADATA_NAME,
    PROFILE,
    SIDE_CHANNELS,
    TOPIC,
    block_batches,
    encode_block,
    side_messages,
)
from sniffer.io.mcap_native import info_metadata
from sniffer.io.output_files import open_new
from sniffer.tool_version import tool_version

#: Uncompressed bytes per chunk. The writer keeps every chunk's index entry (with an offset
#: per channel) until it writes the summary: 4 MiB chunks keep that to ~0.5 MB a million frames,
#: where 1 MiB chunks grew a day's export by 64 MB.
CHUNK_SIZE = 4 << 20
_FLAG_SUFFIXES = Table([suffix.encode() for suffix in FLAG_SUFFIXES])

_NUMBER_OR_NULL = {"type": ["number", "null"]}
_INT_OR_NULL = {"type": ["integer", "null"]}
_TEXT_OR_NULL = {"type": ["string", "null"]}
FRAME_SCHEMA: dict[str, Any] = {
    "title": "rtusniff.Frame",
    "type": "object",
    "description": "One frame of the capture, as a frame record of `rtusniff analyze --format jsonl`.",
    "properties": {
        "kind": {"type": "string"}, "index": {"type": "integer"}, "t": {"type": "number"},
        "t_end": {"type": "number"}, "t_ns": {"type": "integer"}, "t_end_ns": {"type": "integer"},
        "hex": {"type": "string"}, "crc_ok": {"type": "boolean"}, "slave": _INT_OR_NULL, "function": _INT_OR_NULL,
        "role": {"type": "string"}, "exception_code": _INT_OR_NULL,
        "flags": {"type": "array", "items": {"type": "string"}},
        "request_index": _INT_OR_NULL, "latency_s": _NUMBER_OR_NULL, "summary": {"type": "string"},
        "protocol": {"type": "string"}, "remarks": {"type": "array", "items": {"type": "string"}},
        "params": {"type": "array", "items": {"type": "object", "properties": {
            "address": {"type": "integer"}, "code": _TEXT_OR_NULL, "name": _TEXT_OR_NULL, "raw": _INT_OR_NULL,
            "value": {"type": ["number", "string", "null"]}, "unit": _TEXT_OR_NULL,
            # Only on a value over several registers (optional: not required).
            "words": {"type": "array", "items": {"type": "integer"}}}}},
    },
}  # fmt: skip
FRAME_SCHEMA["required"] = list(FRAME_SCHEMA["properties"])
#: Only on a capture that says which line a frame came from (optional: not required).
FRAME_SCHEMA["properties"]["channel"] = {"type": "string"}
#: Only on a frame with a character the receiver found wrong (optional: not required).
FRAME_SCHEMA["properties"]["uart_errors"] = {"type": "array", "items": {"type": "object", "properties": {
    "at": {"type": "integer"}, "error": {"type": "string", "enum": ["framing", "parity", "framing+parity"]}}}}
TRANSACTION_SCHEMA: dict[str, Any] = {
    "title": "rtusniff.Transaction",
    "type": "object",
    "description": "A request and what became of it.",
    "properties": {
        "request_index": {"type": "integer"}, "answer_index": _INT_OR_NULL, "slave": {"type": "integer"},
        "function": _INT_OR_NULL, "outcome": {"type": "string", "enum": OUTCOMES},
        "latency_s": _NUMBER_OR_NULL, "latency_ms": _NUMBER_OR_NULL, "exception_code": _INT_OR_NULL,
        "request": {"type": "string"}, "answer": _TEXT_OR_NULL,
    },
}  # fmt: skip
TRANSACTION_SCHEMA["required"] = list(TRANSACTION_SCHEMA["properties"])
PARAMS_SCHEMA: dict[str, Any] = {
    "title": "rtusniff.SlaveParams",
    "type": "object",
    "description": "Numeric register values one frame carried, by profile code or by address.",
    "properties": {"index": {"type": "integer"}},
    "required": ["index"],
    "additionalProperties": {"type": "number"},
}


class MessageWriter(Protocol):
    """Where the decoded channels go: an MCAP file (:class:`ColumnarMcapWriter`) or a live
    Foxglove server (:class:`sniffer.exports.foxglove_server.FoxgloveServerWriter`)."""

    def add_schema(self, name: str, encoding: str, data: bytes) -> int: ...

    def add_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]) -> int: ...

    def write(self, block: MessageBlock) -> None: ...

    def close(self) -> None: ...


class DecodedChannels:
    """The decoded channels (frames, transactions, params per slave, log) built a batch at a
    time as columns and handed to a :class:`MessageWriter` as blocks: one definition for the
    MCAP file and the live Foxglove stream, so a layout made on one works on the other."""

    def __init__(self, writer: MessageWriter, info: CaptureInfo, *, target: str) -> None:
        #: What the messages go to, as errors name it (a file, the Foxglove stream).
        self.target = target
        self._writer = writer
        self._frames = self._json_channel("/modbus/frames", FRAME_SCHEMA)
        self._transactions = self._json_channel("/modbus/transactions", TRANSACTION_SCHEMA)
        log_schema = self._writer.add_schema(
            foxglove_log.SCHEMA_NAME, foxglove_log.ENCODING, foxglove_log.FILE_DESCRIPTOR_SET
        )
        self._log = self._writer.add_channel("/modbus/log", foxglove_log.ENCODING, log_schema, {})
        self._params_schema = self._writer.add_schema(
            PARAMS_SCHEMA["title"], "jsonschema", json.dumps(PARAMS_SCHEMA).encode()
        )
        #: Keeps a write's values as the JSON members its params message would carry.
        self._published: PublishedValues[bytes] = PublishedValues()
        #: ``/slave/N/params`` channel ids by slave, made when a slave first carries values.
        self._param_channels = np.zeros(256, np.uint16)
        self._frame_records = FrameRecordEncoder(exact=False)
        self._frame_records.channels = info.channels
        self._log_encoder = foxglove_log.LogEncoder(_LOG_NAMES)

    def _json_channel(self, topic: str, schema: dict[str, Any]) -> int:
        schema_id = self._writer.add_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
        return self._writer.add_channel(topic, "json", schema_id, {})

    def messages(self, batch: AnnotatedBatch, fields: BlockFields | None = None) -> None:
        """A batch's frames, log lines and params (their decoded texts: :mod:`sniffer.encoding.decoded_texts`).
        ``fields``: what of the frame records no decoding says, made where frames were paired
        (:func:`~sniffer.encoding.frame_fields.block_fields`)."""
        positions = batch.positions()
        if not positions:
            return
        kept = np.array(positions, np.int64)
        messages, frames = batch.messages, batch.messages.frames
        t_ns, slaves = frames.t_start_ns[kept], messages.slave[kept]
        heads, values = self._heads_and_values(batch, messages.role)
        values = self._published_values(batch, kept, values)
        indexes = number_texts(kept + frames.first_index)
        self._write(self._frame_records.block_rows(batch, HEADER_SIZE, fields=fields), self._frames, t_ns)
        text: list[Column] = [b"#", indexes, heads, _FLAG_SUFFIXES.column(messages.flags[kept])]
        log_rows = self._log_encoder.rows(t_ns, log_levels(messages)[kept], text, slaves, HEADER_SIZE)
        self._write(log_rows, self._log, t_ns)
        self._params(values, indexes, slaves, t_ns)

    def _published_values(self, batch: AnnotatedBatch, kept: npt.NDArray[np.int64], values: list[bytes]) -> list[bytes]:
        """``values`` of the messages whose values are published (valid answers), with the values
        of the writes they accept; ``b""`` for the rest (:mod:`sniffer.exports.published`)."""
        # What a write request wrote is its own values.
        published, accepted = self._published.select(batch, kept, values.__getitem__)
        if not published.all():
            values = [value if keep else b"" for value, keep in zip(values, published.tolist(), strict=True)]
        for row, members in accepted:
            if members:
                values[row] = b"".join((values[row][:-1], b",", members)) if values[row] else members
        return values

    def transactions(self, rows: Rows, t_ns: npt.NDArray[np.int64]) -> None:
        """A batch's ``/modbus/transactions`` messages, built by
        :class:`~sniffer.exports.transactions.TransactionEncoder` (``reserved=HEADER_SIZE``)."""
        self._write(rows, self._transactions, t_ns)

    def _write(self, rows: Rows, channels: npt.NDArray[np.uint16] | int, t_ns: npt.NDArray[np.int64]) -> None:
        if len(t_ns) and int(t_ns.min()) < 0:
            raise RtuSniffError(
                ErrorKind.OUTPUT_FAILED, f"a frame starts {-int(t_ns.min()) / 1e9:.6f} s before 1970 (a capture whose "
                "clock starts at 0, as a logic analyzer's does): MCAP times are nanoseconds since 1970 and cannot "
                "be earlier; --pcap, --rrd and analyze --format jsonl take such times", path=self.target)
        if isinstance(channels, int):
            channels = np.full(len(rows), channels, np.uint16)
        self._writer.write(MessageBlock(rows, channels, t_ns))

    def _params(self, values: list[bytes], indexes: list[bytes], slaves: Integers, t_ns: npt.NDArray[np.int64]) -> None:
        """A message per answer or write that carried values (read requests carry only
        addresses: no values, ``b""``), on its slave's channel."""
        carried = (np.fromiter(map(len, values), np.int64, len(values)) > 0) & (slaves != NONE)
        rows = np.flatnonzero(carried)
        if not len(rows):
            return
        for slave in distinct(slaves[rows]).tolist():
            if not self._param_channels[slave]:
                self._param_channels[slave] = self._writer.add_channel(
                    f"/slave/{slave}/params", "json", self._params_schema, {}
                )
        picked = rows.tolist()
        columns: list[Column] = [b'{"index":', [indexes[row] for row in picked], b",", [values[row] for row in picked]]
        self._write(join_rows(columns, len(picked), HEADER_SIZE), self._param_channels[slaves[rows]], t_ns[rows])

    @staticmethod
    def _heads_and_values(batch: AnnotatedBatch, roles: Integers) -> tuple[list[bytes], list[bytes]]:
        """Per message written: the log text after the frame index, and its numeric params as
        JSON members (``b""``: it carried no values)."""
        return (each_message(batch, lambda parts: parts.log_heads(roles)),
                each_message(batch, FrameTexts.numeric_members))

    def log_line(self, t_ns: int, level: int, text: str) -> None:
        """One line of rtusniff's own on ``/modbus/log`` (a gap in a live capture's decoding)."""
        times = np.array([t_ns], np.int64)
        rows = self._log_encoder.rows(times, np.array([level], np.uint8), [[text.encode()]],
                                      np.array([_OWN_LOG], np.int64), HEADER_SIZE)
        self._write(rows, self._log, times)

    def close(self) -> None:
        self._writer.close()


class McapExporter(DecodedChannels):
    """Decoded MCAP: the decoded channels next to the raw chunks of the native capture format,
    with the capture's and the export's metadata first."""

    def __init__(self, path: str, info: CaptureInfo, line: LineSettings, metadata: dict[str, str]) -> None:
        self.path = path
        self._file: BinaryIO = open_new(path)
        tool = tool_version()
        self._mcap = ColumnarMcapWriter(self._file, profile=PROFILE, library=tool, chunk_size=CHUNK_SIZE)
        try:
            # Metadata first: a reader of the capture finds the line settings before any block.
            self._mcap.add_metadata(METADATA_NAME, info_metadata(info))
            export = {**metadata, "line": line.format(), "timing": info.timing.value, "tool": tool}
            self._mcap.add_metadata("rtusniff.export", export)
            self._raw = self._mcap.add_channel(TOPIC, MESSAGE_ENCODING, 0, {"layout": LAYOUT_DOC})
            self._side_channels: dict[str, int] = {}
            super().__init__(self._mcap, info, target=path)
            self._mcap.flush()
        except BaseException:
            self._abandon()
            raise

    def raw(self, batch: ChunkBatch) -> None:
        """The capture's chunks as the native capture has them (so the export reads back as a
        capture), each block's side messages (UART errors, channels) just before it."""
        payloads, channels, times = [], [], []
        for block in block_batches(batch):
            t_first = int(block.t_end_ns[0])
            for topic, payload in side_messages(block):
                if topic not in self._side_channels:
                    encoding, layout = SIDE_CHANNELS[topic]
                    self._side_channels[topic] = self._mcap.add_channel(topic, encoding, 0, {"layout": layout})
                payloads.append(payload)
                channels.append(self._side_channels[topic])
                times.append(t_first)
            payloads.append(encode_block(block))
            channels.append(self._raw)
            times.append(t_first)
        rows = join_rows([payloads], len(payloads), HEADER_SIZE)
        self._write(rows, np.array(channels, np.uint16), np.array(times, np.int64))

    def incomplete(self, frames: int) -> None:
        """Metadata record ``rtusniff.incomplete``: the export was interrupted after ``frames``
        frames (what it holds; a reader of the capture sees its raw chunks up to there)."""
        self._mcap.add_metadata("rtusniff.incomplete", {"reason": "interrupted", "frames": str(frames)})

    def close(self) -> None:
        try:
            self._mcap.close()
        finally:
            self._file.close()

    def _abandon(self) -> None:
        with contextlib.suppress(OSError):
            self._mcap.close()
        with contextlib.suppress(OSError):
            self._file.close()


def transaction_encoder() -> TransactionEncoder:
    """The encoder of what :meth:`McapExporter.transactions` writes: it needs no decodings, so it
    may run in the decoding process (``prepare`` in :func:`sniffer.pipeline.analyze`)."""
    return TransactionEncoder(HEADER_SIZE)


class Prepared(NamedTuple):
    """What of a batch's messages needs no decoding (``prepare``, where frames are paired):
    its ``/modbus/transactions`` messages and their times, its frame records' own fields."""

    transactions: Rows
    t_ns: npt.NDArray[np.int64]
    fields: BlockFields


def preparer() -> Callable[[MessageBatch], Prepared]:
    """The MCAP export's ``prepare``."""
    encoder = transaction_encoder()

    def prepare(batch: MessageBatch) -> Prepared:
        return Prepared(*encoder.rows(batch, np.arange(len(batch))), block_fields(batch))

    return prepare


#: The log's ``name`` by slave, then rtusniff's own lines; NONE (-1, noise) is the last.
_LOG_NAMES = [f"slave {slave}" for slave in range(256)] + ["rtusniff", "noise"]
_OWN_LOG = 256
