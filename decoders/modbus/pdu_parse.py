"""The parsers of PDUs, one per layout and direction (:mod:`decoders.modbus.codecs` says which
function code takes which).

A parser raises :class:`ShortPduError` where the bytes do not fit its layout; :func:`parsed`
makes that a :class:`~decoders.modbus.pdu.Malformed` PDU, so that decoding never raises on bus
data.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from itertools import chain

from decoders.modbus.layouts import MEI_READ_DEVICE_ID
from decoders.modbus.pdu import (
    AltivarMeiError,
    BitsResponse,
    ExceptionPdu,
    Malformed,
    MaskWrite,
    Pdu,
    RawPdu,
    ReadRequest,
    ReadWriteRequest,
    RegistersResponse,
    WriteCoilsRequest,
    WriteMultipleResponse,
    WriteRegistersRequest,
    WriteSingle,
)
from decoders.modbus.pdu_serial import (
    CommEventCounter,
    CommEventLog,
    DeviceIdObject,
    DeviceIdRequest,
    DeviceIdResponse,
    Diagnostics,
    ExceptionStatus,
    FifoRequest,
    FifoResponse,
    FileReadResponse,
    FileRecords,
    FileSubRequest,
    MeiRaw,
    NoData,
    ServerId,
)

Parser = Callable[[int, bytes], Pdu]


class ShortPduError(ValueError):
    """The PDU ends before its layout does."""


def _words(data: bytes) -> tuple[int, ...]:
    if len(data) % 2:
        raise ShortPduError(f"{len(data)} data bytes is not a whole number of registers")
    return struct.unpack(f">{len(data) // 2}H", data)


#: The bits of each byte value as 0 and 1, LSB first: a coil frame is decoded a byte at a time,
#: not a bit, and its runs take the bits as their values as they are.
_BYTE_BITS = [tuple(byte >> i & 1 for i in range(8)) for byte in range(256)]


def _bits(data: bytes, count: int | None = None) -> tuple[int, ...]:
    bits = tuple(chain.from_iterable(map(_BYTE_BITS.__getitem__, data)))
    return bits if count is None else bits[:count]


def _u16(data: bytes, offset: int) -> int:
    if len(data) < offset + 2:
        raise ShortPduError(f"ends at byte {len(data)}, needs {offset + 2}")
    value: int = (data[offset] << 8) | data[offset + 1]
    return value


def _counted(data: bytes, offset: int = 0) -> tuple[int, bytes]:
    """A byte count at ``offset`` and the bytes it counts, which must be all the rest."""
    if len(data) <= offset:
        raise ShortPduError("no byte count")
    count = data[offset]
    payload = data[offset + 1 :]
    if len(payload) != count:
        raise ShortPduError(f"byte count {count} but {len(payload)} bytes follow")
    return count, payload


def _exact(data: bytes, length: int) -> None:
    if len(data) != length:
        raise ShortPduError(f"{len(data)} data bytes, the layout has {length}")


def read_request(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return ReadRequest(function, _u16(data, 0), _u16(data, 2))


def bits_response(function: int, data: bytes) -> Pdu:
    count, payload = _counted(data)
    return BitsResponse(function, count, _bits(payload))


def registers_response(function: int, data: bytes) -> Pdu:
    count, payload = _counted(data)
    return RegistersResponse(function, count, _words(payload))


def write_single(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return WriteSingle(function, _u16(data, 0), _u16(data, 2))


def no_data(function: int, data: bytes) -> Pdu:
    _exact(data, 0)
    return NoData(function)


def exception_status(function: int, data: bytes) -> Pdu:
    _exact(data, 1)
    return ExceptionStatus(data[0])


def diagnostics(function: int, data: bytes) -> Pdu:
    return Diagnostics(_u16(data, 0), data[2:])


def comm_event_counter(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return CommEventCounter(_u16(data, 0), _u16(data, 2))


def comm_event_log(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    return CommEventLog(_u16(payload, 0), _u16(payload, 2), _u16(payload, 4), payload[6:])


def write_coils(function: int, data: bytes) -> Pdu:
    address, count = _u16(data, 0), _u16(data, 2)
    _, payload = _counted(data, 4)
    return WriteCoilsRequest(address, count, _bits(payload, count))


def write_registers(function: int, data: bytes) -> Pdu:
    address, count = _u16(data, 0), _u16(data, 2)
    _, payload = _counted(data, 4)
    return WriteRegistersRequest(address, count, _words(payload))


def write_multiple_response(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return WriteMultipleResponse(function, _u16(data, 0), _u16(data, 2))


def server_id(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    return ServerId(payload)


def file_records(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    items, offset = [], 0
    while offset < len(payload):
        if len(payload) < offset + 7:
            raise ShortPduError("file sub-request cut short")
        length = _u16(payload, offset + 5)
        words: tuple[int, ...] = ()
        if function == 21:
            words = _words(payload[offset + 7 : offset + 7 + 2 * length])
            if len(words) != length:
                raise ShortPduError("file record data cut short")
        file, record = _u16(payload, offset + 1), _u16(payload, offset + 3)
        items.append(FileSubRequest(payload[offset], file, record, length, words))
        offset += 7 + 2 * len(words)
    return FileRecords(function, tuple(items))


def file_read_response(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    groups, offset = [], 0
    while offset < len(payload):
        length = payload[offset]
        if length < 1 or len(payload) < offset + 1 + length:
            raise ShortPduError("file response group cut short")
        groups.append(_words(payload[offset + 2 : offset + 1 + length]))
        offset += 1 + length
    return FileReadResponse(tuple(groups))


def mask_write(function: int, data: bytes) -> Pdu:
    _exact(data, 6)
    return MaskWrite(_u16(data, 0), _u16(data, 2), _u16(data, 4))


def read_write_request(function: int, data: bytes) -> Pdu:
    read_address, read_count = _u16(data, 0), _u16(data, 2)
    write_address, write_count = _u16(data, 4), _u16(data, 6)
    _, payload = _counted(data, 8)
    return ReadWriteRequest(read_address, read_count, write_address, write_count, _words(payload))


def fifo_request(function: int, data: bytes) -> Pdu:
    _exact(data, 2)
    return FifoRequest(_u16(data, 0))


def fifo_response(function: int, data: bytes) -> Pdu:
    byte_count, fifo_count = _u16(data, 0), _u16(data, 2)
    if byte_count != len(data) - 2 or fifo_count * 2 + 2 != byte_count:
        raise ShortPduError(f"byte count {byte_count} and FIFO count {fifo_count} do not match {len(data) - 2} bytes")
    return FifoResponse(_words(data[4:]))


def mei_request(function: int, data: bytes) -> Pdu:
    if data[:1] == bytes([MEI_READ_DEVICE_ID]):
        _exact(data, 3)
        return DeviceIdRequest(data[1], data[2])
    return MeiRaw(data[0], data[1:]) if data else _no_mei()


def mei_response(function: int, data: bytes) -> Pdu:
    if data[:1] != bytes([MEI_READ_DEVICE_ID]):
        return MeiRaw(data[0], data[1:]) if data else _no_mei()
    if len(data) < 6:
        raise ShortPduError("device identification header cut short")
    objects, offset = [], 6
    for _ in range(data[5]):
        if len(data) < offset + 2 or len(data) < offset + 2 + data[offset + 1]:
            raise ShortPduError("device identification object cut short")
        objects.append(DeviceIdObject(data[offset], data[offset + 2 : offset + 2 + data[offset + 1]]))
        offset += 2 + data[offset + 1]
    if offset != len(data):
        raise ShortPduError(f"{len(data) - offset} bytes after the last object")
    return DeviceIdResponse(data[1], data[2], data[3] == 0xFF, data[4], tuple(objects))


def _no_mei() -> Pdu:
    raise ShortPduError("no MEI type")


def raw(function: int, data: bytes) -> Pdu:
    """A PDU rtusniff knows no layout of (a device's own function code): its bytes."""
    return RawPdu(function, data)


def exception(function: int, data: bytes) -> Pdu:
    """An exception response (its function code without the exception bit)."""
    if function == 43 and len(data) == 2 and data[0] == MEI_READ_DEVICE_ID:
        return AltivarMeiError(data[1])
    if len(data) != 1:
        return Malformed(function, f"exception with {len(data)} data bytes instead of 1", data)
    return ExceptionPdu(function, data[0])


def parsed(parser: Parser, function: int, data: bytes) -> Pdu:
    """``parser``'s PDU of ``data``; :class:`~decoders.modbus.pdu.Malformed` where the bytes do
    not fit its layout. Never raises."""
    try:
        return parser(function, data)
    except ShortPduError as exc:
        return Malformed(function, str(exc), data)
