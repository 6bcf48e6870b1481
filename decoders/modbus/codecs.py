"""One codec per function code: what rtusniff knows of each, in one registry.

A :class:`Codec` holds a function code's length rules per direction (what lets the framer find
its frames by content where timing cannot be trusted: the framing rule tables are built from
:data:`LAYOUTS`), its request and response parsers (:mod:`decoders.modbus.pdu_parse`; each
PDU type writes its own summary) and the shape in which its frames are decoded in bulk as well
(:data:`BULK_SHAPES`; :mod:`decoders.modbus.columnar_find` chooses by it alone, into what the
parsers and PDUs would say). Adding a function code is one entry of :data:`CODECS`;
``docs/architecture.md`` walks through one.

The names Modbus gives its function codes and data tables (:mod:`decoders.modbus.codes`) lie
below the PDUs, whose summaries say them; a code without a standard name is named "User-defined
function N" or "Unknown function N" there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.message import Role
from decoders.modbus.codes import BIT_FUNCTIONS, EXCEPTION_BIT, function_name
from decoders.modbus.layouts import (
    Layout,
    LengthRule,
    counted,
    exception_length,
    fixed,
    mei_request_length,
    mei_response_length,
)
from decoders.modbus.pdu import Malformed, Pdu, RawPdu
from decoders.modbus.pdu_parse import (
    Parser,
    bits_response,
    comm_event_counter,
    comm_event_log,
    diagnostics,
    exception,
    exception_status,
    fifo_request,
    fifo_response,
    file_read_response,
    file_records,
    mask_write,
    mei_request,
    mei_response,
    no_data,
    parsed,
    raw,
    read_request,
    read_write_request,
    registers_response,
    server_id,
    write_coils,
    write_multiple_response,
    write_registers,
    write_single,
)

#: The registry, and the names outputs read through it (a function's name is kept in ``codes``,
#: below the PDUs whose summaries say it).
__all__ = ["CODECS", "LAYOUTS", "Codec", "fits_request", "fits_response", "function_name", "parse_as", "parse_pdu"]

#: The shapes of exchange whose frames are decoded in bulk (:mod:`decoders.modbus.columnar_find`
#: reads them, and nothing else, to choose): a read of a span (an 8-byte request for an address
#: and a count, answered by a byte count and the data); a single write (8 bytes, echoed); a
#: multiple write (a span's values, confirmed by its address and count); a read/write (a span's
#: values written and another read, answered as a read). Their values are bits (coils, discrete
#: inputs) for the functions of :data:`~decoders.modbus.codes.BIT_FUNCTIONS`, else registers.
NOT_IN_BULK, BULK_READ, BULK_SINGLE, BULK_MULTIPLE, BULK_READ_WRITE = range(5)


@dataclass(frozen=True, slots=True)
class Codec:
    """A function code's length rules, how its requests and responses are parsed
    (:func:`~decoders.modbus.pdu_parse.raw` keeps the bytes of a layout not parsed), and the
    shape in which its frames are also decoded in bulk (``NOT_IN_BULK``: one by one only)."""

    layout: Layout
    request: Parser = raw
    response: Parser = raw
    bulk: int = NOT_IN_BULK


_READ = Layout(fixed(8), counted(2, 5))
_WRITE_SINGLE = Layout(fixed(8), fixed(8))
_WRITE_MULTIPLE = Layout(counted(6, 9), fixed(8))
_COUNTED_BOTH = Layout(counted(2, 5), counted(2, 5))

#: Every function code rtusniff knows, by code (Modbus Application Protocol V1.1b3, and the
#: Altivar's FC 43 negative answer).
CODECS: dict[int, Codec] = {
    1: Codec(_READ, read_request, bits_response, BULK_READ),
    2: Codec(_READ, read_request, bits_response, BULK_READ),
    3: Codec(_READ, read_request, registers_response, BULK_READ),
    4: Codec(_READ, read_request, registers_response, BULK_READ),
    5: Codec(_WRITE_SINGLE, write_single, write_single, BULK_SINGLE),
    6: Codec(_WRITE_SINGLE, write_single, write_single, BULK_SINGLE),
    7: Codec(Layout(fixed(4), fixed(5)), no_data, exception_status),
    8: Codec(Layout(fixed(8), fixed(8)), diagnostics, diagnostics),
    11: Codec(Layout(fixed(4), fixed(8)), no_data, comm_event_counter),
    12: Codec(Layout(fixed(4), counted(2, 5)), no_data, comm_event_log),
    15: Codec(_WRITE_MULTIPLE, write_coils, write_multiple_response, BULK_MULTIPLE),
    16: Codec(_WRITE_MULTIPLE, write_registers, write_multiple_response, BULK_MULTIPLE),
    17: Codec(Layout(fixed(4), counted(2, 5)), no_data, server_id),
    20: Codec(_COUNTED_BOTH, file_records, file_read_response),
    21: Codec(_COUNTED_BOTH, file_records, file_records),
    22: Codec(Layout(fixed(10), fixed(10)), mask_write, mask_write),
    23: Codec(Layout(counted(10, 13), counted(2, 5)), read_write_request, registers_response,
              BULK_READ_WRITE),
    24: Codec(Layout(fixed(6), counted(2, 6, size=2)), fifo_request, fifo_response),
    43: Codec(Layout(LengthRule(special=mei_request_length), LengthRule(special=mei_response_length)),
              mei_request, mei_response),
}
#: The length rules by function code (the framer's view of :data:`CODECS`).
LAYOUTS: dict[int, Layout] = {code: codec.layout for code, codec in CODECS.items()}
#: Each function's bulk shape, by code (the 257th: none, for a frame of no function, ``NONE``).
BULK_SHAPES: npt.NDArray[np.int8] = np.zeros(257, np.int8)
for _code, _codec in CODECS.items():
    BULK_SHAPES[_code] = _codec.bulk
#: Whether a function's values are bits, by code (as :data:`BULK_SHAPES`).
BIT_VALUES: npt.NDArray[np.bool_] = np.zeros(257, np.bool_)
BIT_VALUES[sorted(BIT_FUNCTIONS)] = True
#: Roles whose frames are read as requests.
_AS_REQUEST = {Role.REQUEST, Role.BROADCAST}


def parse_as(adu: bytes, role: Role) -> Pdu:
    """:func:`parse_pdu` of a frame of ``role``: a request or broadcast as a request, a frame of
    no known role as one where it has a request's length, the rest as a response."""
    is_request = role in _AS_REQUEST or (role is Role.UNKNOWN and fits_request(adu))
    return parse_pdu(adu, is_request=is_request)


def parse_pdu(adu: bytes, *, is_request: bool) -> Pdu:
    """Decode ``adu`` (address, PDU, CRC) as a request or as a response. Never raises: bytes that
    do not fit their layout are :class:`~decoders.modbus.pdu.Malformed`, a code no codec knows
    :class:`~decoders.modbus.pdu.RawPdu`."""
    if len(adu) < 4:
        return Malformed(adu[1] & ~EXCEPTION_BIT if len(adu) > 1 else 0, "shorter than a frame", adu)
    raw_function, data = adu[1], adu[2:-2]
    function = raw_function & ~EXCEPTION_BIT
    if raw_function & EXCEPTION_BIT:
        return exception(function, data)
    codec = CODECS.get(function)
    if codec is None:
        return RawPdu(function, data)
    return parsed(codec.request if is_request else codec.response, function, data)


def fits_request(adu: bytes) -> bool:
    """Whether ``adu`` has exactly the length of a request of its function code."""
    codec = CODECS.get(adu[1]) if len(adu) >= 2 else None
    return codec is not None and codec.layout.request(adu) == len(adu)


def fits_response(adu: bytes) -> bool:
    """Whether ``adu`` has exactly the length of a (normal or exception) response."""
    if len(adu) < 2:
        return False
    if adu[1] & EXCEPTION_BIT:
        return exception_length(adu) == len(adu)
    codec = CODECS.get(adu[1])
    return codec is not None and codec.layout.response(adu) == len(adu)
