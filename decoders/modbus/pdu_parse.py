"""Frame bytes to typed PDUs: :func:`parse_pdu`, one parser per function code and direction.

It never raises on bus data: bytes that do not fit their layout become
:class:`~decoders.modbus.pdu.Malformed`, codes without a layout
:class:`~decoders.modbus.pdu.RawPdu`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from itertools import chain

from decoders.message import Role
from decoders.modbus.codes import EXCEPTION_BIT
from decoders.modbus.layouts import MEI_READ_DEVICE_ID, fits_request
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

#: Roles whose frames are read as requests.
_AS_REQUEST = {Role.REQUEST, Role.BROADCAST}

Parser = Callable[[int, bytes], Pdu]


class _ShortPduError(ValueError):
    """The PDU ends before its layout does."""


def _words(data: bytes) -> tuple[int, ...]:
    if len(data) % 2:
        raise _ShortPduError(f"{len(data)} data bytes is not a whole number of registers")
    return struct.unpack(f">{len(data) // 2}H", data)


#: The bits of each byte value as 0 and 1, LSB first: a coil frame is decoded a byte at a time,
#: not a bit, and its runs take the bits as their values as they are.
_BYTE_BITS = [tuple(byte >> i & 1 for i in range(8)) for byte in range(256)]


def _bits(data: bytes, count: int | None = None) -> tuple[int, ...]:
    bits = tuple(chain.from_iterable(map(_BYTE_BITS.__getitem__, data)))
    return bits if count is None else bits[:count]


def _u16(data: bytes, offset: int) -> int:
    if len(data) < offset + 2:
        raise _ShortPduError(f"ends at byte {len(data)}, needs {offset + 2}")
    value: int = (data[offset] << 8) | data[offset + 1]
    return value


def _counted(data: bytes, offset: int = 0) -> tuple[int, bytes]:
    """A byte count at ``offset`` and the bytes it counts, which must be all the rest."""
    if len(data) <= offset:
        raise _ShortPduError("no byte count")
    count = data[offset]
    payload = data[offset + 1 :]
    if len(payload) != count:
        raise _ShortPduError(f"byte count {count} but {len(payload)} bytes follow")
    return count, payload


def _exact(data: bytes, length: int) -> None:
    if len(data) != length:
        raise _ShortPduError(f"{len(data)} data bytes, the layout has {length}")


def _read_request(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return ReadRequest(function, _u16(data, 0), _u16(data, 2))


def _bits_response(function: int, data: bytes) -> Pdu:
    count, payload = _counted(data)
    return BitsResponse(function, count, _bits(payload))


def _registers_response(function: int, data: bytes) -> Pdu:
    count, payload = _counted(data)
    return RegistersResponse(function, count, _words(payload))


def _write_single(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return WriteSingle(function, _u16(data, 0), _u16(data, 2))


def _no_data(function: int, data: bytes) -> Pdu:
    _exact(data, 0)
    return NoData(function)


def _exception_status(function: int, data: bytes) -> Pdu:
    _exact(data, 1)
    return ExceptionStatus(data[0])


def _diagnostics(function: int, data: bytes) -> Pdu:
    return Diagnostics(_u16(data, 0), data[2:])


def _comm_event_counter(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return CommEventCounter(_u16(data, 0), _u16(data, 2))


def _comm_event_log(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    return CommEventLog(_u16(payload, 0), _u16(payload, 2), _u16(payload, 4), payload[6:])


def _write_coils(function: int, data: bytes) -> Pdu:
    address, count = _u16(data, 0), _u16(data, 2)
    _, payload = _counted(data, 4)
    return WriteCoilsRequest(address, count, _bits(payload, count))


def _write_registers(function: int, data: bytes) -> Pdu:
    address, count = _u16(data, 0), _u16(data, 2)
    _, payload = _counted(data, 4)
    return WriteRegistersRequest(address, count, _words(payload))


def _write_multiple_response(function: int, data: bytes) -> Pdu:
    _exact(data, 4)
    return WriteMultipleResponse(function, _u16(data, 0), _u16(data, 2))


def _server_id(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    return ServerId(payload)


def _file_records(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    items, offset = [], 0
    while offset < len(payload):
        if len(payload) < offset + 7:
            raise _ShortPduError("file sub-request cut short")
        length = _u16(payload, offset + 5)
        words: tuple[int, ...] = ()
        if function == 21:
            words = _words(payload[offset + 7 : offset + 7 + 2 * length])
            if len(words) != length:
                raise _ShortPduError("file record data cut short")
        file, record = _u16(payload, offset + 1), _u16(payload, offset + 3)
        items.append(FileSubRequest(payload[offset], file, record, length, words))
        offset += 7 + 2 * len(words)
    return FileRecords(function, tuple(items))


def _file_read_response(function: int, data: bytes) -> Pdu:
    _, payload = _counted(data)
    groups, offset = [], 0
    while offset < len(payload):
        length = payload[offset]
        if length < 1 or len(payload) < offset + 1 + length:
            raise _ShortPduError("file response group cut short")
        groups.append(_words(payload[offset + 2 : offset + 1 + length]))
        offset += 1 + length
    return FileReadResponse(tuple(groups))


def _mask_write(function: int, data: bytes) -> Pdu:
    _exact(data, 6)
    return MaskWrite(_u16(data, 0), _u16(data, 2), _u16(data, 4))


def _read_write_request(function: int, data: bytes) -> Pdu:
    read_address, read_count = _u16(data, 0), _u16(data, 2)
    write_address, write_count = _u16(data, 4), _u16(data, 6)
    _, payload = _counted(data, 8)
    return ReadWriteRequest(read_address, read_count, write_address, write_count, _words(payload))


def _fifo_request(function: int, data: bytes) -> Pdu:
    _exact(data, 2)
    return FifoRequest(_u16(data, 0))


def _fifo_response(function: int, data: bytes) -> Pdu:
    byte_count, fifo_count = _u16(data, 0), _u16(data, 2)
    if byte_count != len(data) - 2 or fifo_count * 2 + 2 != byte_count:
        raise _ShortPduError(f"byte count {byte_count} and FIFO count {fifo_count} do not match {len(data) - 2} bytes")
    return FifoResponse(_words(data[4:]))


def _mei_request(function: int, data: bytes) -> Pdu:
    if data[:1] == bytes([MEI_READ_DEVICE_ID]):
        _exact(data, 3)
        return DeviceIdRequest(data[1], data[2])
    return MeiRaw(data[0], data[1:]) if data else _no_mei()


def _mei_response(function: int, data: bytes) -> Pdu:
    if data[:1] != bytes([MEI_READ_DEVICE_ID]):
        return MeiRaw(data[0], data[1:]) if data else _no_mei()
    if len(data) < 6:
        raise _ShortPduError("device identification header cut short")
    objects, offset = [], 6
    for _ in range(data[5]):
        if len(data) < offset + 2 or len(data) < offset + 2 + data[offset + 1]:
            raise _ShortPduError("device identification object cut short")
        objects.append(DeviceIdObject(data[offset], data[offset + 2 : offset + 2 + data[offset + 1]]))
        offset += 2 + data[offset + 1]
    if offset != len(data):
        raise _ShortPduError(f"{len(data) - offset} bytes after the last object")
    return DeviceIdResponse(data[1], data[2], data[3] == 0xFF, data[4], tuple(objects))


def _no_mei() -> Pdu:
    raise _ShortPduError("no MEI type")


REQUEST_PARSERS: dict[int, Parser] = {
    1: _read_request, 2: _read_request, 3: _read_request, 4: _read_request,
    5: _write_single, 6: _write_single, 7: _no_data, 8: _diagnostics, 11: _no_data, 12: _no_data,
    15: _write_coils, 16: _write_registers, 17: _no_data, 20: _file_records, 21: _file_records,
    22: _mask_write, 23: _read_write_request, 24: _fifo_request, 43: _mei_request,
}  # fmt: skip
RESPONSE_PARSERS: dict[int, Parser] = {
    1: _bits_response, 2: _bits_response, 3: _registers_response, 4: _registers_response,
    5: _write_single, 6: _write_single, 7: _exception_status, 8: _diagnostics, 11: _comm_event_counter,
    12: _comm_event_log, 15: _write_multiple_response, 16: _write_multiple_response, 17: _server_id,
    20: _file_read_response, 21: _file_records, 22: _mask_write, 23: _registers_response,
    24: _fifo_response, 43: _mei_response,
}  # fmt: skip


def parse_as(adu: bytes, role: Role) -> Pdu:
    """:func:`parse_pdu` of a frame of ``role``: a request or broadcast as a request, a frame of
    no known role as one where it has a request's length, the rest as a response."""
    is_request = role in _AS_REQUEST or (role is Role.UNKNOWN and fits_request(adu))
    return parse_pdu(adu, is_request=is_request)


def parse_pdu(adu: bytes, *, is_request: bool) -> Pdu:
    """Decode ``adu`` (address, PDU, CRC) as a request or as a response. Never raises."""
    if len(adu) < 4:
        return Malformed(adu[1] & ~EXCEPTION_BIT if len(adu) > 1 else 0, "shorter than a frame", adu)
    raw_function, data = adu[1], adu[2:-2]
    function = raw_function & ~EXCEPTION_BIT
    if raw_function & EXCEPTION_BIT:
        return _exception(function, data)
    parser = (REQUEST_PARSERS if is_request else RESPONSE_PARSERS).get(function)
    if parser is None:
        return RawPdu(function, data)
    try:
        return parser(function, data)
    except _ShortPduError as exc:
        return Malformed(function, str(exc), data)


def _exception(function: int, data: bytes) -> Pdu:
    if function == 43 and len(data) == 2 and data[0] == MEI_READ_DEVICE_ID:
        return AltivarMeiError(data[1])
    if len(data) != 1:
        return Malformed(function, f"exception with {len(data)} data bytes instead of 1", data)
    return ExceptionPdu(function, data[0])
