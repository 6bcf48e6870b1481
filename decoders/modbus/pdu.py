"""Typed Modbus PDUs, per function code and direction: reading and writing data, exceptions,
and what fits no layout; :data:`Pdu` is the union of these and of the serial-line PDUs
(:mod:`decoders.modbus.pdu_serial`).

:func:`decoders.modbus.codecs.parse_pdu` turns a frame's bytes into one of them. Bytes that
do not fit their layout become :class:`Malformed`, codes without a layout :class:`RawPdu`. Each
PDU says what it is in one line (``summary``); the line is derived from the typed fields.
"""

from __future__ import annotations

from dataclasses import dataclass

from decoders.modbus.codes import (
    ALTIVAR_MEI_ERRORS,
    MAX_QUANTITY,
    MAX_READ_WRITE_QUANTITY,
    TABLE_NAMES,
    exception_name,
    function_name,
)
from decoders.modbus.pdu_serial import (  # for the union Pdu; import them from pdu_serial
    CommEventCounter,
    CommEventLog,
    DeviceIdRequest,
    DeviceIdResponse,
    Diagnostics,
    ExceptionStatus,
    FifoRequest,
    FifoResponse,
    FileReadResponse,
    FileRecords,
    MeiRaw,
    NoData,
    ServerId,
)
from decoders.modbus.pdu_text import hex_words, registers

COIL_ON = 0xFF00
COIL_OFF = 0x0000
#: What an FC 5 write's value says (any other value: ``invalid 0x…``).
COIL_STATES = {COIL_ON: "ON", COIL_OFF: "OFF"}


def _range(address: int, count: int) -> str:
    return f"{address}" if count == 1 else f"{address}..{address + count - 1}"


def _quantity(count: int, limit: int) -> str:
    """The count in a summary; one Modbus does not allow says so (the slave answers exception 03)."""
    return f"{count}" if 1 <= count <= limit else f"{count}, Modbus allows 1..{limit}"


def quantity_allowed(pdu: Pdu) -> bool:
    """Whether a request (or a write's echo) names no more registers or coils than Modbus allows.
    (``isinstance`` rather than a ``match``: asked once for every frame decoded anew.)"""
    if isinstance(pdu, ReadRequest | WriteMultipleResponse):
        return 1 <= pdu.count <= MAX_QUANTITY[pdu.function]
    if isinstance(pdu, ReadWriteRequest):
        read_limit, write_limit = MAX_READ_WRITE_QUANTITY
        return 1 <= pdu.read_count <= read_limit and 1 <= pdu.write_count <= write_limit
    return True


#: Bits (0 and 1) as digits, translated in C: a bit at a time costs a call each.
_BIT_DIGITS = bytes.maketrans(b"\x00\x01", b"01")


def _bit_string(bits: tuple[int, ...], limit: int = 32) -> str:
    shown = bytes(bits[:limit]).translate(_BIT_DIGITS).decode()
    return shown + ("…" if len(bits) > limit else "")


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
        return f"read {TABLE_NAMES[self.function]} {_range(self.address, self.count)} ({count})"


@dataclass(slots=True, unsafe_hash=True)
class BitsResponse:
    """FC 1, 2 response: every bit of the data bytes, LSB of the first byte first."""

    function: int
    byte_count: int
    bits: tuple[int, ...]  # 0 and 1

    def summary(self) -> str:
        return f"{TABLE_NAMES[self.function]} = {_bit_string(self.bits)} ({self.byte_count} bytes)"


@dataclass(slots=True, unsafe_hash=True)
class RegistersResponse:
    """FC 3, 4, 23 response."""

    function: int
    byte_count: int
    values: tuple[int, ...]

    def summary(self) -> str:
        # A device's own read-shaped function names its table, or reads registers.
        return f"{TABLE_NAMES.get(self.function, 'HR')} = {hex_words(self.values)} ({registers(len(self.values))})"


@dataclass(slots=True, unsafe_hash=True)
class WriteSingle:
    """FC 5 and 6, request and (echoed) response."""

    function: int
    address: int
    value: int

    def summary(self) -> str:
        if self.function == 5:
            state = COIL_STATES.get(self.value, f"invalid 0x{self.value:04X}")
            return f"write coil {self.address} = {state}"
        return f"write HR {self.address} = {self.value} (0x{self.value:04X})"


@dataclass(slots=True, unsafe_hash=True)
class WriteCoilsRequest:
    """FC 15 request."""

    address: int
    count: int
    bits: tuple[int, ...]  # 0 and 1

    def summary(self) -> str:
        return f"write coils {_range(self.address, self.count)} = {_bit_string(self.bits)}"


@dataclass(slots=True, unsafe_hash=True)
class WriteRegistersRequest:
    """FC 16 request."""

    address: int
    count: int
    values: tuple[int, ...]

    def summary(self) -> str:
        return f"write HR {_range(self.address, self.count)} = {hex_words(self.values)}"


@dataclass(slots=True, unsafe_hash=True)
class WriteMultipleResponse:
    """FC 15, 16 response."""

    function: int
    address: int
    count: int

    def summary(self) -> str:
        count = _quantity(self.count, MAX_QUANTITY[self.function])
        return f"wrote {TABLE_NAMES[self.function]} {_range(self.address, self.count)} ({count})"


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
            f"write HR {_range(self.write_address, self.write_count)} = {hex_words(self.values)}"
        )


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
