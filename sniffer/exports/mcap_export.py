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
line, profiles. zstd chunks and the summary section with its indexes come from the mcap writer.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from importlib.metadata import version
from typing import Any

from mcap.well_known import MessageEncoding, SchemaEncoding

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.frame import FrameFlag
from decoders.line import LineSettings
from decoders.message import AnnotatedBatch, Message, Role
from sniffer.exports import foxglove_log
from sniffer.io.formats.mcap_capture import McapCaptureWriter
from sniffer.views.records import FrameRecordEncoder, encode_json

KEPT_REQUESTS = 4096
CHUNK_SIZE = 1 << 20
LOG_LEVELS = {"debug": 1, "info": 2, "warning": 3, "error": 4}
ERROR_FLAGS = FrameFlag.TIMEOUT
WARNING_FLAGS = FrameFlag.GAP_1_5 | FrameFlag.SHORT_IDLE | FrameFlag.RETRY | FrameFlag.UNEXPECTED

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
            "value": {"type": ["number", "string", "null"]}, "unit": _TEXT_OR_NULL}}},
    },
}  # fmt: skip
TRANSACTION_SCHEMA: dict[str, Any] = {
    "title": "rtusniff.Transaction",
    "type": "object",
    "description": "A request and what became of it.",
    "properties": {
        "request_index": {"type": "integer"}, "answer_index": _INT_OR_NULL, "slave": {"type": "integer"},
        "function": _INT_OR_NULL, "outcome": {"type": "string",
                                             "enum": ["answered", "exception", "crc_error", "timeout", "broadcast"]},
        "latency_s": _NUMBER_OR_NULL, "latency_ms": _NUMBER_OR_NULL, "exception_code": _INT_OR_NULL,
        "request": {"type": "string"}, "answer": _TEXT_OR_NULL,
    },
}  # fmt: skip
PARAMS_SCHEMA: dict[str, Any] = {
    "title": "rtusniff.SlaveParams",
    "type": "object",
    "description": "Numeric register values one frame carried, by profile code or by address.",
    "properties": {"index": {"type": "integer"}},
    "additionalProperties": {"type": "number"},
}


def log_level(message: Message) -> int:
    """ERROR for CRC errors, timeouts and exceptions; WARNING for timing and retry flags, noise."""
    if message.role is Role.NOISE:
        return LOG_LEVELS["warning"]
    if not message.frame.crc_ok or message.flags & ERROR_FLAGS or message.role is Role.EXCEPTION:
        return LOG_LEVELS["error"]
    if message.flags & WARNING_FLAGS:
        return LOG_LEVELS["warning"]
    return LOG_LEVELS["info"]


def numeric_params(message: Message) -> dict[str, float | int]:
    """The values a frame carried, by code (or address), numbers only: state words give their raw value."""
    values: dict[str, float | int] = {}
    for param in message.params:
        if param.raw is None:
            continue
        key = param.code if param.code is not None else str(param.address)
        values[key] = param.value if isinstance(param.value, int | float) else param.raw
    return values


class McapExporter:
    """Writes the decoded channels next to the raw chunks of the native capture format."""

    def __init__(self, path: str, info: CaptureInfo, line: LineSettings, metadata: dict[str, str]) -> None:
        self._capture = McapCaptureWriter(path, info, chunk_size=CHUNK_SIZE)
        self._writer = self._capture.writer
        self._writer.add_metadata("rtusniff.export", {
            **metadata, "line": line.format(), "timing": info.timing.value, "tool": f"rtusniff {version('rtusniff')}",
        })
        self._frames = self._channel("/modbus/frames", FRAME_SCHEMA)
        self._frame_records = FrameRecordEncoder()
        self._transactions = self._channel("/modbus/transactions", TRANSACTION_SCHEMA)
        log_schema = self._writer.register_schema(name=foxglove_log.SCHEMA_NAME, encoding=foxglove_log.ENCODING,
                                                  data=foxglove_log.FILE_DESCRIPTOR_SET)
        self._log = self._writer.register_channel(topic="/modbus/log", message_encoding=foxglove_log.ENCODING,
                                                  schema_id=log_schema)
        self._params_schema = self._schema(PARAMS_SCHEMA)
        self._param_channels: dict[int, int] = {}
        self._requests: OrderedDict[int, tuple[str, int, int | None, int]] = OrderedDict()
        self.counts: dict[str, int] = {}

    def _schema(self, schema: dict[str, Any]) -> int:
        schema_id: int = self._writer.register_schema(name=schema["title"], encoding=SchemaEncoding.JSONSchema,
                                                      data=json.dumps(schema).encode())
        return schema_id

    def _channel(self, topic: str, schema: dict[str, Any]) -> int:
        return self._writer.register_channel(topic=topic, message_encoding=MessageEncoding.JSON,
                                             schema_id=self._schema(schema))

    def raw(self, batch: ChunkBatch) -> None:
        self._capture.write_batch(batch)

    def messages(self, batch: AnnotatedBatch) -> None:
        for message, record in zip(batch, self._frame_records.encode_batch(batch), strict=True):
            self._message(message, record.encode())

    def _put(self, channel: int, topic: str, t_ns: int, record: dict[str, Any]) -> None:
        self._writer.add_message(channel_id=channel, log_time=t_ns, publish_time=t_ns,
                                 data=encode_json(record))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _message(self, message: Message, frame_record: bytes) -> None:
        frame = message.frame
        t_ns = frame.t_start_ns
        self._writer.add_message(channel_id=self._frames, log_time=t_ns, publish_time=t_ns,
                                 data=frame_record)
        self.counts["/modbus/frames"] = self.counts.get("/modbus/frames", 0) + 1
        seconds, nanos = divmod(t_ns, 1_000_000_000)
        name = "noise" if message.slave is None else f"slave {message.slave}"
        text = f"#{frame.index} {message.role.value}: {message.summary}"
        if message.flags:
            text += f" [{' '.join(message.flags.names)}]"
        self._writer.add_message(channel_id=self._log, log_time=t_ns, publish_time=t_ns,
                                 data=foxglove_log.encode_log(seconds, nanos, log_level(message), text, name))
        self.counts["/modbus/log"] = self.counts.get("/modbus/log", 0) + 1
        self._transaction(message)
        # Answers and writes carry values; read requests carry only addresses.
        values = numeric_params(message)
        if values and message.slave is not None:
            self._put(self._slave_channel(message.slave), f"/slave/{message.slave}/params", t_ns,
                      {"index": frame.index, **values})

    def _slave_channel(self, slave: int) -> int:
        if slave not in self._param_channels:
            self._param_channels[slave] = self._writer.register_channel(
                topic=f"/slave/{slave}/params", message_encoding=MessageEncoding.JSON, schema_id=self._params_schema)
        return self._param_channels[slave]

    def _transaction(self, message: Message) -> None:
        frame, role = message.frame, message.role
        if role is Role.REQUEST:
            if message.flags & FrameFlag.TIMEOUT:
                self._put_transaction(frame.t_end_ns, frame.index, frame.data.hex(), message, outcome="timeout",
                                      answer=None)
            else:
                self._requests[frame.index] = (frame.data.hex(), message.slave or 0, message.function, frame.t_end_ns)
                if len(self._requests) > KEPT_REQUESTS:
                    self._requests.popitem(last=False)
        elif role is Role.BROADCAST:
            self._put_transaction(frame.t_end_ns, frame.index, frame.data.hex(), message, outcome="broadcast",
                                  answer=None)
        elif message.request_index is not None and message.request_index in self._requests:
            request_hex, *_ = self._requests.pop(message.request_index)
            outcome = "exception" if role is Role.EXCEPTION else "answered" if frame.crc_ok else "crc_error"
            self._put_transaction(frame.t_start_ns, message.request_index, request_hex, message, outcome=outcome,
                                  answer=frame.index)

    def _put_transaction(
        self, t_ns: int, request_index: int, request_hex: str, message: Message, *, outcome: str, answer: int | None
    ) -> None:
        latency = None if message.latency_ns is None or answer is None else message.latency_ns / 1e9
        self._put(self._transactions, "/modbus/transactions", t_ns, {
            "request_index": request_index, "answer_index": answer, "slave": message.slave,
            "function": message.function, "outcome": outcome, "latency_s": latency,
            "latency_ms": None if latency is None else latency * 1e3, "exception_code": message.exception_code,
            "request": request_hex, "answer": None if answer is None else message.frame.data.hex(),
        })

    def close(self) -> None:
        self._capture.close()
