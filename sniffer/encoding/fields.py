"""The frame record's fields, in one table: name, JSON type, meaning.

The frame record is spelled in five places, each fast in its own way: the dict
(:func:`sniffer.encoding.records.frame_record`), the JSONL column encoder and the MCAP
fixed-width rows (:class:`sniffer.encoding.records.FrameRecordEncoder`), the MCAP JSON
schema (``FRAME_SCHEMA`` in :mod:`sniffer.exports.mcap_export`) and the field tables
of ``docs/jsonl-output.md``. ``tests/test_record_fields.py`` holds all five to this
table: same names, in this order where order is part of the output, same types.
Adding a field is a line here, then each place the test names.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Field:
    """One field of the frame record."""

    name: str
    #: The JSON schema types the value may have.
    types: tuple[str, ...]
    meaning: str
    #: Only in some records (after the others, in this order), absent from the rest.
    optional: bool = False


FRAME_FIELDS: tuple[Field, ...] = (
    Field("kind", ("string",), 'record type: "frame"'),
    Field("index", ("integer",), "position of the frame in the capture, from 0"),
    Field("t", ("number",), "start of the frame's first byte, seconds since the epoch"),
    Field("t_end", ("number",), "end of the frame's last byte"),
    Field("t_ns", ("integer",), "t as integer nanoseconds"),
    Field("t_end_ns", ("integer",), "t_end as integer nanoseconds"),
    Field("hex", ("string",), "the frame's bytes, lower-case hex"),
    Field("crc_ok", ("boolean",), "the CRC holds"),
    Field("slave", ("integer", "null"), "unit address; null for noise"),
    Field("function", ("integer", "null"), "function code without the exception bit"),
    Field("role", ("string",), "request, response, exception, broadcast, noise or unknown"),
    Field("exception_code", ("integer", "null"), "for exception responses"),
    Field("flags", ("array",), "conditions found on the frame"),
    Field("request_index", ("integer", "null"), "for answers: index of the request"),
    Field("latency_s", ("number", "null"), "for answers on exact captures: silence after the request"),
    Field("params", ("array",), "registers or coils the frame names, with names, units and values"),
    Field("summary", ("string",), "one human-readable line"),
    Field("protocol", ("string",), "modbus or uss"),
    Field("remarks", ("array",), "what the device profile says about the frame"),
    Field("channel", ("string",), "the line the frame came from (RX, TX; inbound, outbound)", optional=True),
    Field("uart_errors", ("array",), "characters the receiver found wrong: byte position and error", optional=True),
)

#: The fields every frame record has, in order.
FRAME_FIELD_NAMES = tuple(field.name for field in FRAME_FIELDS if not field.optional)
#: The fields some frame records add after those.
OPTIONAL_FRAME_FIELD_NAMES = tuple(field.name for field in FRAME_FIELDS if field.optional)
