"""``foxglove.Log`` in protobuf, encoded by hand: both Foxglove and Rerun render it.

Foxglove's Log panel reads ``foxglove.Log`` in JSON or protobuf; Rerun, opening an MCAP,
turns only the protobuf one into a text log (JSON channels stay opaque). The message has
six fields (Foxglove's schema, schemas/proto/foxglove/Log.proto), so the protobuf wire
format and the schema's FileDescriptorSet are written here in a few lines rather than
pulling in the protobuf runtime.
"""

from __future__ import annotations

SCHEMA_NAME = "foxglove.Log"
ENCODING = "protobuf"

_VARINT, _FIXED64, _LENGTH, _FIXED32 = 0, 1, 2, 5
# FieldDescriptorProto enums (google/protobuf/descriptor.proto)
_OPTIONAL = 1
_INT32, _INT64, _FIXED32_TYPE, _STRING, _MESSAGE, _ENUM = 5, 3, 7, 9, 11, 14
_SMALL = [bytes([value]) for value in range(0x80)]


def _varint(value: int) -> bytes:
    if 0 <= value < 0x80:  # one byte: lengths and small numbers
        return _SMALL[value]
    if 0 <= value < 1 << 35:  # up to five bytes, unrolled: every timestamp's nanoseconds
        if value < 1 << 14:
            return bytes((value & 0x7F | 0x80, value >> 7))
        if value < 1 << 21:
            return bytes((value & 0x7F | 0x80, value >> 7 & 0x7F | 0x80, value >> 14))
        if value < 1 << 28:
            return bytes((value & 0x7F | 0x80, value >> 7 & 0x7F | 0x80, value >> 14 & 0x7F | 0x80, value >> 21))
        return bytes((value & 0x7F | 0x80, value >> 7 & 0x7F | 0x80, value >> 14 & 0x7F | 0x80,
                      value >> 21 & 0x7F | 0x80, value >> 28))
    value &= (1 << 64) - 1
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def _key(field: int, wire: int) -> bytes:
    return _varint(field << 3 | wire)


def _bytes(field: int, data: bytes) -> bytes:
    return _key(field, _LENGTH) + _varint(len(data)) + data


def _text(field: int, text: str) -> bytes:
    return _bytes(field, text.encode())


def _number(field: int, value: int) -> bytes:
    return _key(field, _VARINT) + _varint(value)


class LogEncoder:
    """``foxglove.Log`` messages (file empty, line 0: proto3 leaves them out). One per frame of
    a capture, so the constant parts are encoded once: the current second, names, levels."""

    def __init__(self) -> None:
        self._second = 0
        self._seconds_field = b""
        self._names: dict[str, bytes] = {}

    def encode(self, t_ns: int, level: int, message: bytes, name: str) -> bytes:
        seconds, nanos = divmod(t_ns, 1_000_000_000)
        if seconds != self._second:
            self._second, self._seconds_field = seconds, _number(1, seconds)
        name_field = self._names.get(name)
        if name_field is None:
            name_field = self._names[name] = _text(4, name)
        timestamp = self._seconds_field + (_NANOS_KEY + _varint(nanos) if nanos else b"")
        return b"".join((_TIMESTAMP_KEY, _varint(len(timestamp)), timestamp, _LEVELS[level], _MESSAGE_KEY,
                         _varint(len(message)), message, name_field))


_TIMESTAMP_KEY, _NANOS_KEY, _MESSAGE_KEY = _key(1, _LENGTH), _key(2, _VARINT), _key(3, _LENGTH)
_LEVELS = [_number(2, level) for level in range(6)]


def _field(name: str, number: int, kind: int, type_name: str = "") -> bytes:
    return (_text(1, name) + _number(3, number) + _number(4, _OPTIONAL) + _number(5, kind)
            + (_text(6, type_name) if type_name else b""))


def _file_descriptor_set() -> bytes:
    seconds_and_nanos = _bytes(2, _field("seconds", 1, _INT64)) + _bytes(2, _field("nanos", 2, _INT32))
    timestamp = (
        _text(1, "google/protobuf/timestamp.proto") + _text(2, "google.protobuf")
        + _bytes(4, _text(1, "Timestamp") + seconds_and_nanos)
        + _text(12, "proto3")
    )
    levels = b"".join(_bytes(2, _text(1, name) + _number(2, number)) for number, name in
                      enumerate(["UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"]))
    log = (
        _text(1, "Log")
        + _bytes(2, _field("timestamp", 1, _MESSAGE, ".google.protobuf.Timestamp"))
        + _bytes(2, _field("level", 2, _ENUM, ".foxglove.Log.Level"))
        + _bytes(2, _field("message", 3, _STRING)) + _bytes(2, _field("name", 4, _STRING))
        + _bytes(2, _field("file", 5, _STRING)) + _bytes(2, _field("line", 6, _FIXED32_TYPE))
        + _bytes(4, _text(1, "Level") + levels)
    )
    foxglove = (_text(1, "foxglove/Log.proto") + _text(2, "foxglove") + _text(3, "google/protobuf/timestamp.proto")
                + _bytes(4, log) + _text(12, "proto3"))
    return _bytes(1, timestamp) + _bytes(1, foxglove)


FILE_DESCRIPTOR_SET = _file_descriptor_set()
