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
line, profiles. Written with foxglove-sdk's MCAP writer (Rust; 4× the messages per second of the
pure-Python ``mcap`` writer, measured in benchmarks/bench_exports.py): zstd chunks, a summary
section with its indexes. Messages are built from the batches' columns, and what a decoding
determines (log text, numeric params) is built once per decoding.
"""

from __future__ import annotations

import contextlib
import json
import logging
import re
from collections import OrderedDict
from collections.abc import Callable
from importlib.metadata import version
from typing import Any

import foxglove
from foxglove import Channel, Context, Schema
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from decoders.capture import CaptureInfo, ChunkBatch
from decoders.line import LineSettings
from decoders.memo import Memo
from decoders.message import NONE, ROLE_CODE, ROLE_ORDER, AnnotatedBatch, Decoding, Role
from decoders.modbus.annotate import KEPT_DECODINGS
from sniffer.exports import foxglove_log
from sniffer.exports.levels import FLAG_SUFFIXES, TIMEOUT, log_levels
from sniffer.io.formats.mcap_capture import (
    LAYOUT_DOC,
    MESSAGE_ENCODING,
    METADATA_NAME,
    PROFILE,
    TOPIC,
    encode_blocks,
    info_metadata,
)
from sniffer.views.records import FrameRecordEncoder, encode_json

KEPT_REQUESTS = 4096
#: Uncompressed bytes per chunk. The writer keeps every chunk's index entry (with an offset
#: per channel) until it writes the summary: 4 MiB chunks keep that to ~0.5 MB a million frames,
#: where 1 MiB chunks grew a day's export by 64 MB.
CHUNK_SIZE = 4 << 20
#: Frames between flushes, which is where a failed write (a full disk) shows.
FLUSH_FRAMES = 100_000
_REQUEST, _BROADCAST, _EXCEPTION = (ROLE_CODE[role] for role in (Role.REQUEST, Role.BROADCAST, Role.EXCEPTION))
_FLAG_SUFFIXES = [suffix.encode() for suffix in FLAG_SUFFIXES]

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


class _WriteFailure(logging.Handler):
    """Keeps the first error foxglove-sdk logs: its writer logs a failed write (a full disk) once
    per message and raises only a generic error at the next flush, without the cause."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.cause: str | None = None

    def emit(self, record: logging.LogRecord) -> None:
        if self.cause is None:
            text = record.getMessage()
            found = re.search(r'message: "([^"]+)"', text)
            self.cause = found.group(1) if found else text


def numeric_params(decoding: Decoding) -> dict[str, float | int]:
    """The values a frame carried, by code (or address), numbers only: state words give their raw value."""
    values: dict[str, float | int] = {}
    for param in decoding.params:
        if param.raw is None:
            continue
        key = param.code if param.code is not None else str(param.address)
        values[key] = param.value if isinstance(param.value, int | float) else param.raw
    return values


class McapExporter:
    """Writes the decoded channels next to the raw chunks of the native capture format."""

    def __init__(self, path: str, info: CaptureInfo, line: LineSettings, metadata: dict[str, str]) -> None:
        # A context of its own: nothing else that logs through foxglove-sdk reaches this file.
        self._context = Context()
        # Its log would repeat a write failure for every message; the error is said once, here.
        self._failure = _WriteFailure()
        sdk_log = logging.getLogger("foxglove")
        sdk_log.addHandler(self._failure)
        sdk_log.propagate = False
        options = MCAPWriteOptions(compression=MCAPCompression.Zstd, chunk_size=CHUNK_SIZE, profile=PROFILE,
                                   compression_threads=0)
        self._writer = foxglove.open_mcap(path, allow_overwrite=True, context=self._context, writer_options=options)
        tool = f"rtusniff {version('rtusniff')}"
        export = {**metadata, "line": line.format(), "timing": info.timing.value, "tool": tool}
        try:
            # Metadata first: a reader of the capture finds the line settings before any block.
            self._written(lambda: self._writer.write_metadata(METADATA_NAME, info_metadata(info)))
            self._written(lambda: self._writer.write_metadata("rtusniff.export", export))
        except OSError:
            # Closed now, or the writer tries again (and complains) when it is collected.
            with contextlib.suppress(RuntimeError):
                self._writer.close()
            raise
        self._raw = Channel(TOPIC, schema=Schema(name=MESSAGE_ENCODING, encoding="", data=b""),
                            message_encoding=MESSAGE_ENCODING, context=self._context, metadata={"layout": LAYOUT_DOC})
        self._frames = self._json_channel("/modbus/frames", FRAME_SCHEMA)
        self._transactions = self._json_channel("/modbus/transactions", TRANSACTION_SCHEMA)
        log_schema = Schema(name=foxglove_log.SCHEMA_NAME, encoding=foxglove_log.ENCODING,
                            data=foxglove_log.FILE_DESCRIPTOR_SET)
        self._log = Channel("/modbus/log", schema=log_schema, message_encoding=foxglove_log.ENCODING,
                            context=self._context)
        self._param_channels: dict[int, Channel] = {}
        self._frame_records = FrameRecordEncoder()
        self._log_encoder = foxglove_log.LogEncoder()
        #: Per decoding: the log text after the frame index, and the numeric params as JSON members.
        self._parts: Memo[Decoding, tuple[bytes, bytes | None]] = Memo(KEPT_DECODINGS)
        #: Open requests by index: their hex.
        self._requests: OrderedDict[int, str] = OrderedDict()
        self._unflushed = 0
        #: The log's ``name`` per slave column value (NONE: noise).
        self._log_names = {NONE: "noise", **{slave: f"slave {slave}" for slave in range(256)}}

    def _json_channel(self, topic: str, schema: dict[str, Any]) -> Channel:
        return Channel(topic, schema=Schema(name=schema["title"], encoding="jsonschema",
                                            data=json.dumps(schema).encode()),
                       message_encoding="json", context=self._context)

    def raw(self, batch: ChunkBatch) -> None:
        for t_first, payload in encode_blocks(batch):
            self._raw.log(payload, log_time=t_first)

    def messages(self, batch: AnnotatedBatch) -> None:
        positions = batch.positions()
        messages, frames = batch.messages, batch.messages.frames
        columns = zip(
            self._frame_records.encode_batch(batch),
            frames.t_start_ns[positions].tolist(),
            log_levels(messages)[positions].tolist(),
            messages.flags[positions].tolist(),
            messages.slave[positions].tolist(),
            messages.role[positions].tolist(),
            strict=True,
        )
        first, decodings, names = frames.first_index, batch.decodings, self._log_names
        # The Rust channel's own log, without the Python wrapper's checks: three calls per frame.
        frames_log, log_log, log_encode = self._frames.base.log, self._log.base.log, self._log_encoder.encode
        for position, (record, t_ns, level, flags, slave, role) in zip(positions, columns, strict=True):
            frames_log(record.encode(), t_ns, None)
            decoding = decodings[position]
            parts = self._parts.get(decoding) or self._decoding_parts(decoding, ROLE_ORDER[role])
            text = b"#%d%s%s" % (first + position, parts[0], _FLAG_SUFFIXES[flags])
            log_log(log_encode(t_ns, level, text, names[slave]), t_ns, None)
            # Answers and writes carry values; read requests carry only addresses.
            if parts[1] is not None and slave != NONE:
                self._slave_channel(slave).base.log(b'{"index":%d,%s' % (first + position, parts[1]), t_ns, None)
        self._transactions_of(batch, positions)
        self._unflushed += len(positions)
        if self._unflushed >= FLUSH_FRAMES:
            self._unflushed = 0
            self._written(self._writer.flush)

    def _decoding_parts(self, decoding: Decoding, role: Role) -> tuple[bytes, bytes | None]:
        values = numeric_params(decoding)
        parts = (f" {role.value}: {decoding.summary}".encode(), encode_json(values)[1:] if values else None)
        self._parts.put(decoding, parts)
        return parts

    def _slave_channel(self, slave: int) -> Channel:
        channel = self._param_channels.get(slave)
        if channel is None:
            channel = self._param_channels[slave] = self._json_channel(f"/slave/{slave}/params", PARAMS_SCHEMA)
        return channel

    def _transactions_of(self, batch: AnnotatedBatch, positions: list[int]) -> None:
        """Requests and what became of them: answered, exception, crc_error, timeout, broadcast."""
        messages, frames = batch.messages, batch.messages.frames
        data, offsets, first = frames.data, frames.offsets.tolist(), frames.first_index
        columns = zip(
            messages.role[positions].tolist(), messages.flags[positions].tolist(),
            messages.request_index[positions].tolist(), frames.t_start_ns[positions].tolist(),
            frames.t_end_ns[positions].tolist(), frames.crc_ok[positions].tolist(),
            messages.slave[positions].tolist(), messages.function[positions].tolist(),
            messages.exception_code[positions].tolist(), messages.latency_ns[positions].tolist(),
            strict=True,
        )
        for position, (role, flags, paired_with, t_start, t_end, ok, slave, function, code, latency) in zip(
            positions, columns, strict=True
        ):
            hex_data = data[offsets[position] : offsets[position + 1]].hex()
            index = first + position
            if role == _REQUEST and not flags & TIMEOUT:
                self._requests[index] = hex_data
                if len(self._requests) > KEPT_REQUESTS:
                    self._requests.popitem(last=False)
                continue
            if role in (_REQUEST, _BROADCAST):
                outcome = "timeout" if role == _REQUEST else "broadcast"
                t_ns, request, request_hex, answer = t_end, index, hex_data, None
            elif paired_with != NONE and paired_with in self._requests:
                outcome = "exception" if role == _EXCEPTION else "answered" if ok else "crc_error"
                t_ns, request, request_hex, answer = t_start, paired_with, self._requests.pop(paired_with), index
            else:
                continue
            seconds = None if latency == NONE or answer is None else latency / 1e9
            self._transactions.base.log(encode_json({
                "request_index": request, "answer_index": answer, "slave": None if slave == NONE else slave,
                "function": None if function == NONE else function, "outcome": outcome, "latency_s": seconds,
                "latency_ms": None if seconds is None else seconds * 1e3,
                "exception_code": None if code == NONE else code, "request": request_hex,
                "answer": None if answer is None else hex_data,
            }), t_ns, None)

    def _written(self, step: Callable[[], None]) -> None:
        """Runs a step that writes the file, which is where foxglove-sdk reports a failed write."""
        try:
            step()
        except RuntimeError as exc:
            raise OSError(self._failure.cause or str(exc)) from None

    def close(self) -> None:
        try:
            self._written(self._writer.close)
        finally:
            sdk_log = logging.getLogger("foxglove")
            sdk_log.removeHandler(self._failure)
            sdk_log.propagate = True
