"""Length rules: how long a request or a response of each function code is.

A passive tap sees both directions on one wire, and a function code's request and
response have different layouts. Each rule gives the whole ADU length (address,
function, data, CRC) from the first bytes of the frame, or ``None`` while too few
bytes are known to tell.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from decoders.modbus.codes import EXCEPTION_BIT

#: Address + function + CRC.
ADU_OVERHEAD = 4
MAX_ADU = 256
EXCEPTION_LENGTH = 5
#: Altivar's negative answer to FC 43: address, 0xAB, MEI type 0x0E, code, CRC.
MEI_EXCEPTION_LENGTH = 6
MEI_READ_DEVICE_ID = 0x0E

LengthFn = Callable[[bytes], int | None]


@dataclass(frozen=True, slots=True)
class LengthRule:
    """How long a frame is: ``fixed`` bytes, or ``base`` plus a byte count of ``size``
    bytes (big-endian) read at ``position``, or what ``special`` computes."""

    fixed: int | None = None
    position: int | None = None
    base: int = 0
    size: int = 1
    special: LengthFn | None = None

    def __call__(self, adu: bytes) -> int | None:
        """The whole ADU length, or ``None`` while too few bytes are known."""
        if self.fixed is not None:
            return self.fixed
        if self.position is not None:
            if len(adu) < self.position + self.size:
                return None
            return self.base + int.from_bytes(adu[self.position : self.position + self.size], "big")
        assert self.special is not None
        return self.special(adu)


def fixed(length: int) -> LengthRule:
    """A frame of always ``length`` bytes."""
    return LengthRule(fixed=length)


def counted(position: int, base: int, size: int = 1) -> LengthRule:
    """A frame whose byte count (``size`` bytes, big-endian) sits at ``position``."""
    return LengthRule(position=position, base=base, size=size)


def device_id_response(adu: bytes) -> int | None:
    """FC 43 / MEI 14 response: walk the (id, length, value) objects."""
    # address, 2B, 0E, read code, conformity, more follows, next id, object count
    header = 8
    if len(adu) < header:
        return None
    position = header
    for _ in range(adu[7]):
        if len(adu) < position + 2:
            return None
        position += 2 + adu[position + 1]
    return position + 2


def _mei_request(adu: bytes) -> int | None:
    """FC 43 request: MEI 14 (read device identification) is 7 bytes; others unknown."""
    if len(adu) < 3:
        return None
    return 7 if adu[2] == MEI_READ_DEVICE_ID else None


def _mei_response(adu: bytes) -> int | None:
    if len(adu) < 3:
        return None
    return device_id_response(adu) if adu[2] == MEI_READ_DEVICE_ID else None


@dataclass(frozen=True, slots=True)
class Layout:
    """The length rules of one function code, per direction."""

    request: LengthRule
    response: LengthRule


_READ_BITS_OR_REGISTERS = Layout(fixed(8), counted(2, 5))
_WRITE_SINGLE = Layout(fixed(8), fixed(8))
_WRITE_MULTIPLE = Layout(counted(6, 9), fixed(8))
_COUNTED_BOTH = Layout(counted(2, 5), counted(2, 5))

LAYOUTS: dict[int, Layout] = {
    1: _READ_BITS_OR_REGISTERS,
    2: _READ_BITS_OR_REGISTERS,
    3: _READ_BITS_OR_REGISTERS,
    4: _READ_BITS_OR_REGISTERS,
    5: _WRITE_SINGLE,
    6: _WRITE_SINGLE,
    7: Layout(fixed(4), fixed(5)),
    8: Layout(fixed(8), fixed(8)),
    11: Layout(fixed(4), fixed(8)),
    12: Layout(fixed(4), counted(2, 5)),
    15: _WRITE_MULTIPLE,
    16: _WRITE_MULTIPLE,
    17: Layout(fixed(4), counted(2, 5)),
    20: _COUNTED_BOTH,
    21: _COUNTED_BOTH,
    22: Layout(fixed(10), fixed(10)),
    23: Layout(counted(10, 13), counted(2, 5)),
    24: Layout(fixed(6), counted(2, 6, size=2)),
    43: Layout(LengthRule(special=_mei_request), LengthRule(special=_mei_response)),
}


def exception_length(adu: bytes) -> int | None:
    """Length of an exception response (function code with bit 7 set)."""
    if len(adu) >= 3 and adu[1] == 43 | EXCEPTION_BIT and adu[2] == MEI_READ_DEVICE_ID:
        return MEI_EXCEPTION_LENGTH
    return EXCEPTION_LENGTH


def fits_request(adu: bytes) -> bool:
    """Whether ``adu`` has exactly the length of a request of its function code."""
    layout = LAYOUTS.get(adu[1]) if len(adu) >= 2 else None
    return layout is not None and layout.request(adu) == len(adu)


def fits_response(adu: bytes) -> bool:
    """Whether ``adu`` has exactly the length of a (normal or exception) response."""
    if len(adu) < 2:
        return False
    if adu[1] & EXCEPTION_BIT:
        return exception_length(adu) == len(adu)
    layout = LAYOUTS.get(adu[1])
    return layout is not None and layout.response(adu) == len(adu)
