"""Typed decoding of Modbus PDUs, per function code and direction.

:func:`parse_pdu` turns a frame's bytes into one of the dataclasses below. It never
raises on bus data: bytes that do not fit their layout become :class:`Malformed`,
codes without a layout :class:`RawPdu`. Each PDU says what it is in one line
(``summary``); the line is derived from the typed fields.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

from decoders.modbus.codes import (
    ALTIVAR_MEI_ERRORS,
    EXCEPTION_BIT,
    MAX_QUANTITY,
    MAX_READ_WRITE_QUANTITY,
    MEI_NAMES,
    READ_DEVICE_ID_CODES,
    USER_DEFINED_FUNCTIONS,
    device_id_object_name,
    diagnostic_name,
    exception_name,
    function_name,
)
from decoders.modbus.layouts import MEI_READ_DEVICE_ID

COIL_ON = 0xFF00
COIL_OFF = 0x0000


class _ShortPduError(ValueError):
    """The PDU ends before its layout does."""


def _words(data: bytes) -> tuple[int, ...]:
    if len(data) % 2:
        raise _ShortPduError(f"{len(data)} data bytes is not a whole number of registers")
    return struct.unpack(f">{len(data) // 2}H", data)


def _bits(data: bytes, count: int | None = None) -> tuple[bool, ...]:
    bits = tuple(bool(byte >> i & 1) for byte in data for i in range(8))
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


def _range(address: int, count: int) -> str:
    return f"{address}" if count == 1 else f"{address}..{address + count - 1}"


def _quantity(count: int, limit: int) -> str:
    """The count in a summary; one Modbus does not allow says so (the slave answers exception 03)."""
    return f"{count}" if 1 <= count <= limit else f"{count}, Modbus allows 1..{limit}"


def quantity_allowed(pdu: Pdu) -> bool:
    """Whether a request (or a write's echo) names no more registers or coils than Modbus allows."""
    match pdu:
        case ReadRequest(function=function, count=count) | WriteMultipleResponse(function=function, count=count):
            return 1 <= count <= MAX_QUANTITY[function]
        case ReadWriteRequest(read_count=read, write_count=write):
            read_limit, write_limit = MAX_READ_WRITE_QUANTITY
            return 1 <= read <= read_limit and 1 <= write <= write_limit
    return True


def _hex_words(values: tuple[int, ...], limit: int = 8) -> str:
    shown = struct.pack(f">{min(len(values), limit)}H", *values[:limit]).hex(" ", 2).upper()
    return shown + (f" … (+{len(values) - limit})" if len(values) > limit else "")


def _bit_string(bits: tuple[bool, ...], limit: int = 32) -> str:
    shown = "".join("1" if b else "0" for b in bits[:limit])
    return shown + ("…" if len(bits) > limit else "")


_TABLES = {1: "coils", 2: "inputs", 3: "HR", 4: "IR"}


# The PDU classes below are not frozen (treat PDUs as immutable: nothing assigns to one): a frozen
# dataclass sets each field through ``object.__setattr__``, 3x slower to build, and a PDU is built
# for every frame decoded anew. ``unsafe_hash``: hashed by value, as a frozen one would be.
@dataclass(slots=True, unsafe_hash=True)
class ReadRequest:
    """FC 1, 2, 3, 4 request."""

    function: int
    address: int
    count: int

    def summary(self) -> str:
        count = _quantity(self.count, MAX_QUANTITY[self.function])
        return f"read {_TABLES[self.function]} {_range(self.address, self.count)} ({count})"


@dataclass(slots=True, unsafe_hash=True)
class BitsResponse:
    """FC 1, 2 response: every bit of the data bytes, LSB of the first byte first."""

    function: int
    byte_count: int
    bits: tuple[bool, ...]

    def summary(self) -> str:
        return f"{_TABLES[self.function]} = {_bit_string(self.bits)} ({self.byte_count} bytes)"


@dataclass(slots=True, unsafe_hash=True)
class RegistersResponse:
    """FC 3, 4, 23 response."""

    function: int
    byte_count: int
    values: tuple[int, ...]

    def summary(self) -> str:
        table = "IR" if self.function == 4 else "HR"
        return f"{table} = {_hex_words(self.values)} ({len(self.values)} registers)"


@dataclass(slots=True, unsafe_hash=True)
class WriteSingle:
    """FC 5 and 6, request and (echoed) response."""

    function: int
    address: int
    value: int

    def summary(self) -> str:
        if self.function == 5:
            state = {COIL_ON: "ON", COIL_OFF: "OFF"}.get(self.value, f"invalid 0x{self.value:04X}")
            return f"write coil {self.address} = {state}"
        return f"write HR {self.address} = {self.value} (0x{self.value:04X})"


@dataclass(slots=True, unsafe_hash=True)
class NoData:
    """A request without data (FC 7, 11, 12, 17)."""

    function: int

    def summary(self) -> str:
        return function_name(self.function).lower()


@dataclass(slots=True, unsafe_hash=True)
class ExceptionStatus:
    """FC 7 response."""

    status: int

    def summary(self) -> str:
        return f"exception status = {self.status:08b}"


@dataclass(slots=True, unsafe_hash=True)
class Diagnostics:
    """FC 8, request or response: a sub-function and its data."""

    sub_function: int
    data: bytes

    @property
    def name(self) -> str:
        return diagnostic_name(self.sub_function)

    def summary(self) -> str:
        shown = self.data.hex(" ").upper() if self.data else "none"
        return f"diagnostics {self.sub_function:02X} {self.name}, data {shown}"


@dataclass(slots=True, unsafe_hash=True)
class CommEventCounter:
    """FC 11 response."""

    status: int
    event_count: int

    def summary(self) -> str:
        busy = "busy" if self.status == 0xFFFF else "ready"
        return f"comm event counter = {self.event_count} ({busy})"


@dataclass(slots=True, unsafe_hash=True)
class CommEventLog:
    """FC 12 response."""

    status: int
    event_count: int
    message_count: int
    events: bytes

    def summary(self) -> str:
        return f"comm events {self.event_count}, messages {self.message_count}, log {self.events.hex(' ').upper()}"


@dataclass(slots=True, unsafe_hash=True)
class WriteCoilsRequest:
    """FC 15 request."""

    address: int
    count: int
    bits: tuple[bool, ...]

    def summary(self) -> str:
        return f"write coils {_range(self.address, self.count)} = {_bit_string(self.bits)}"


@dataclass(slots=True, unsafe_hash=True)
class WriteRegistersRequest:
    """FC 16 request."""

    address: int
    count: int
    values: tuple[int, ...]

    def summary(self) -> str:
        return f"write HR {_range(self.address, self.count)} = {_hex_words(self.values)}"


@dataclass(slots=True, unsafe_hash=True)
class WriteMultipleResponse:
    """FC 15, 16 response."""

    function: int
    address: int
    count: int

    def summary(self) -> str:
        table = "coils" if self.function == 15 else "HR"
        count = _quantity(self.count, MAX_QUANTITY[self.function])
        return f"wrote {table} {_range(self.address, self.count)} ({count})"


@dataclass(slots=True, unsafe_hash=True)
class ServerId:
    """FC 17 response: device-specific id bytes, the run indicator last."""

    data: bytes

    def summary(self) -> str:
        run = {0x00: "OFF", 0xFF: "ON"}.get(self.data[-1], "?") if self.data else "?"
        return f"server id {self.data[:-1].hex(' ').upper() or '-'}, run indicator {run}"


@dataclass(slots=True, unsafe_hash=True)
class FileSubRequest:
    reference_type: int
    file: int
    record: int
    length: int
    data: tuple[int, ...] = ()


@dataclass(slots=True, unsafe_hash=True)
class FileRecords:
    """FC 20 and 21, request and response: a list of file sub-requests or records."""

    function: int
    items: tuple[FileSubRequest, ...]

    def summary(self) -> str:
        verb = "read" if self.function == 20 else "write"
        parts = [f"file {i.file} rec {i.record} len {i.length}" for i in self.items[:4]]
        return f"{verb} file records: {'; '.join(parts) or 'none'}"


@dataclass(slots=True, unsafe_hash=True)
class FileReadResponse:
    """FC 20 response: one group of register words per sub-request."""

    groups: tuple[tuple[int, ...], ...]

    def summary(self) -> str:
        return "file records = " + "; ".join(_hex_words(g, 4) for g in self.groups[:4])


@dataclass(slots=True, unsafe_hash=True)
class MaskWrite:
    """FC 22, request and (echoed) response."""

    address: int
    and_mask: int
    or_mask: int

    def summary(self) -> str:
        return f"mask write HR {self.address}: AND 0x{self.and_mask:04X} OR 0x{self.or_mask:04X}"


@dataclass(slots=True, unsafe_hash=True)
class ReadWriteRequest:
    """FC 23 request."""

    read_address: int
    read_count: int
    write_address: int
    write_count: int
    values: tuple[int, ...]

    def summary(self) -> str:
        return (
            f"read HR {_range(self.read_address, self.read_count)} "
            f"({_quantity(self.read_count, MAX_READ_WRITE_QUANTITY[0])}), "
            f"write HR {_range(self.write_address, self.write_count)} = {_hex_words(self.values)}"
        )


@dataclass(slots=True, unsafe_hash=True)
class FifoRequest:
    """FC 24 request."""

    address: int

    def summary(self) -> str:
        return f"read FIFO at HR {self.address}"


@dataclass(slots=True, unsafe_hash=True)
class FifoResponse:
    """FC 24 response."""

    values: tuple[int, ...]

    def summary(self) -> str:
        return f"FIFO = {_hex_words(self.values)} ({len(self.values)} entries)"


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdRequest:
    """FC 43 / MEI 14 request."""

    read_code: int
    object_id: int

    def summary(self) -> str:
        kind = READ_DEVICE_ID_CODES.get(self.read_code, f"code {self.read_code}")
        return f"read device identification ({kind}) from object {self.object_id}"


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdObject:
    object_id: int
    value: bytes

    @property
    def name(self) -> str:
        return device_id_object_name(self.object_id)

    @property
    def text(self) -> str:
        return self.value.decode("latin-1")


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdResponse:
    """FC 43 / MEI 14 response."""

    read_code: int
    conformity: int
    more_follows: bool
    next_object_id: int
    objects: tuple[DeviceIdObject, ...]

    def summary(self) -> str:
        shown = ", ".join(f"{o.name}={o.text!r}" for o in self.objects)
        more = f", more follows from object {self.next_object_id}" if self.more_follows else ""
        return f"device identification: {shown}{more}"


@dataclass(slots=True, unsafe_hash=True)
class MeiRaw:
    """FC 43 with an MEI type other than 14 (e.g. 13, CANopen general reference)."""

    mei_type: int
    data: bytes

    def summary(self) -> str:
        name = MEI_NAMES.get(self.mei_type, f"MEI type {self.mei_type}")
        return f"{name}: {self.data.hex(' ').upper() or 'no data'}"


@dataclass(slots=True, unsafe_hash=True)
class ExceptionPdu:
    """An exception response: function code with bit 7 set, and an exception code."""

    function: int
    code: int

    @property
    def name(self) -> str:
        return exception_name(self.code)

    def summary(self) -> str:
        return f"exception {self.code:02X} {self.name}"


@dataclass(slots=True, unsafe_hash=True)
class AltivarMeiError:
    """The Altivar's non-standard negative answer to FC 43: ``AB 0E code`` (MEI echoed)."""

    code: int

    def summary(self) -> str:
        meaning = ALTIVAR_MEI_ERRORS.get(self.code, "unknown error")
        return f"device identification refused (Altivar AB 0E {self.code:02X}: {meaning})"


@dataclass(slots=True, unsafe_hash=True)
class RawPdu:
    """A function code without a layout (user-defined or unknown): its data as it is."""

    function: int
    data: bytes

    @property
    def user_defined(self) -> bool:
        return self.function in USER_DEFINED_FUNCTIONS

    def summary(self) -> str:
        return f"{function_name(self.function)}, data {self.data.hex(' ').upper() or 'none'}"


@dataclass(slots=True, unsafe_hash=True)
class Malformed:
    """Bytes that do not fit their function code's layout."""

    function: int
    reason: str
    data: bytes

    def summary(self) -> str:
        return f"malformed {function_name(self.function)}: {self.reason}"


Pdu = (
    ReadRequest | BitsResponse | RegistersResponse | WriteSingle | NoData | ExceptionStatus | Diagnostics
    | CommEventCounter | CommEventLog | WriteCoilsRequest | WriteRegistersRequest | WriteMultipleResponse
    | ServerId | FileRecords | FileReadResponse | MaskWrite | ReadWriteRequest | FifoRequest | FifoResponse
    | DeviceIdRequest | DeviceIdResponse | MeiRaw | ExceptionPdu | AltivarMeiError | RawPdu | Malformed
)
Parser = Callable[[int, bytes], Pdu]


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
