"""Length rules: how long a request or a response is (each function code's:
:mod:`decoders.modbus.codecs`).

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


def mei_request_length(adu: bytes) -> int | None:
    """FC 43 request: MEI 14 (read device identification) is 7 bytes; others unknown."""
    if len(adu) < 3:
        return None
    return 7 if adu[2] == MEI_READ_DEVICE_ID else None


def mei_response_length(adu: bytes) -> int | None:
    if len(adu) < 3:
        return None
    return device_id_response(adu) if adu[2] == MEI_READ_DEVICE_ID else None


@dataclass(frozen=True, slots=True)
class Layout:
    """The length rules of one function code, per direction."""

    request: LengthRule
    response: LengthRule


def exception_length(adu: bytes) -> int | None:
    """Length of an exception response (function code with bit 7 set)."""
    if len(adu) >= 3 and adu[1] == 43 | EXCEPTION_BIT and adu[2] == MEI_READ_DEVICE_ID:
        return MEI_EXCEPTION_LENGTH
    return EXCEPTION_LENGTH
