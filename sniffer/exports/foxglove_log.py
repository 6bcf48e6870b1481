"""``foxglove.Log`` in protobuf, encoded by hand: both Foxglove and Rerun render it.

Foxglove's Log panel reads ``foxglove.Log`` in JSON or protobuf; Rerun, opening an MCAP,
turns only the protobuf one into a text log (JSON channels stay opaque). The message has
six fields (Foxglove's schema, schemas/proto/foxglove/Log.proto), so the protobuf wire
format and the schema's FileDescriptorSet are written here in a few lines rather than
pulling in the protobuf runtime.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct
from sniffer.encoding.rows import Column, Integers, Pieces, Rows, Table, column_sizes, join_rows

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
    """``foxglove.Log`` messages (file empty, line 0: proto3 leaves them out), a batch at a
    time: one per frame of a capture, so the parts are columns (see
    :func:`~sniffer.encoding.rows.join_rows`) and the constant ones are encoded once: seconds,
    names, levels."""

    def __init__(self, names: Sequence[str]) -> None:
        """``names``: the loggers' names, which :meth:`rows` chooses by index."""
        self._seconds: dict[int, bytes] = {}
        self._names = Table([_text(4, name) for name in names])

    def rows(
        self,
        t_ns: npt.NDArray[np.int64],
        levels: npt.NDArray[np.uint8],
        text: Sequence[Column],
        names: Integers,
        reserved: int = 0,
    ) -> Rows:
        """A message per row: its time, level, the text that the ``text`` columns make up, and
        the logger's name (an index into the names given; negative counts from the end)."""
        count = len(t_ns)
        seconds, nanos = np.divmod(t_ns, 1_000_000_000)
        # A batch spans a few seconds: their fields are looked up in C.
        seconds_fields = list(map(self._seconds_fields(seconds).__getitem__, seconds.tolist()))
        nanos_fields = varint_pieces(nanos)
        nanos_keys = Pieces([_NANOS_KEY] * count, np.ones(count, np.int64))
        zero = np.flatnonzero(nanos == 0)  # proto3 leaves a zero out
        nanos_keys.fill(zero, b"")
        nanos_fields.fill(zero, b"")
        timestamp_sizes = np.fromiter(map(len, seconds_fields), np.int64, count) + nanos_keys.sizes + nanos_fields.sizes
        text_sizes = sum((column_sizes(column, count) for column in text), np.zeros(count, np.int64))
        columns: list[Column] = [
            _TIMESTAMP_KEY, varint_pieces(timestamp_sizes), seconds_fields, nanos_keys, nanos_fields,
            _LEVELS.column(levels), _MESSAGE_KEY, varint_pieces(text_sizes), *text,
            self._names.column(names),
        ]  # fmt: skip
        return join_rows(columns, count, reserved)

    def _seconds_fields(self, seconds: npt.NDArray[np.int64]) -> dict[int, bytes]:
        """The ``seconds`` field (proto3 leaves a zero out) of every second in ``seconds``."""
        if len(self._seconds) > 4096:  # a day has 86 400: keep the recent ones
            self._seconds.clear()
        for second in distinct(seconds).tolist():
            if second not in self._seconds:
                self._seconds[second] = _number(1, second) if second else b""
        return self._seconds


def varint_pieces(values: npt.NDArray[np.int64]) -> Pieces:
    """Each value as a protobuf varint (with the varints' sizes), for a column at once: the
    seven-bit groups are cut by numpy, and the varints of each size become ``bytes`` in one
    ``tolist`` (of a void view). Values must lie in ``0 .. 2**35`` (five bytes: nanoseconds,
    lengths); others are encoded one by one."""
    count = len(values)
    if count and (int(values.min()) < 0 or int(values.max()) >= 1 << 35):
        pieces = [_varint(value) for value in values.tolist()]
        return Pieces(pieces, np.fromiter(map(len, pieces), np.int64, count))
    unsigned = values.astype(np.uint64)
    sizes = np.ones(count, np.int64)
    for bits in (7, 14, 21, 28):
        sizes += unsigned >= np.uint64(1 << bits)
    groups = np.empty((count, 5), np.uint8)
    for place in range(5):
        groups[:, place] = (unsigned >> np.uint64(7 * place)) & np.uint64(0x7F)
    groups[:, :4] |= ((np.arange(1, 5) < sizes[:, None]) * 0x80).astype(np.uint8)
    found = np.empty(count, object)
    for size in range(1, 6):
        rows = np.flatnonzero(sizes == size)
        if len(rows):
            found[rows] = np.ascontiguousarray(groups[rows, :size]).view(f"V{size}").ravel().tolist()
    return Pieces(found.tolist(), sizes)


_TIMESTAMP_KEY, _NANOS_KEY, _MESSAGE_KEY = _key(1, _LENGTH), _key(2, _VARINT), _key(3, _LENGTH)
_LEVELS = Table([_number(2, level) if level else b"" for level in range(6)])  # proto3 leaves zeros out


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
