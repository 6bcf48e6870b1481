"""Params as runs against params spelt out case by case: the same registers for any frame."""

from __future__ import annotations

import struct

from hypothesis import given
from hypothesis import strategies as st

from decoders.crc import crc_bytes
from decoders.message import ParamValue
from decoders.modbus.codecs import parse_pdu
from decoders.modbus.param_runs import expand_runs, param_runs
from decoders.modbus.pdu import (
    COIL_ON,
    BitsResponse,
    MaskWrite,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    RegistersResponse,
    WriteCoilsRequest,
    WriteMultipleResponse,
    WriteRegistersRequest,
    WriteSingle,
    quantity_allowed,
)


def reference_params(pdu: Pdu, request: Pdu | None) -> tuple[ParamValue, ...]:
    """A param per register or coil, spelt out case by case (the rule before runs)."""
    if not quantity_allowed(pdu):
        return ()
    start = request.address if isinstance(request, ReadRequest) else \
        request.read_address if isinstance(request, ReadWriteRequest) else None
    match pdu:
        case ReadRequest(address=address, count=count) | WriteMultipleResponse(address=address, count=count):
            return tuple(ParamValue(a) for a in range(address, address + count))
        case RegistersResponse(values=values):
            return () if start is None else tuple(ParamValue(start + i, None, None, v, v) for i, v in enumerate(values))
        case BitsResponse(bits=bits) if isinstance(request, ReadRequest):
            return tuple(ParamValue(request.address + i, raw=int(b), value=int(b))
                         for i, b in enumerate(bits[: request.count]))
        case WriteSingle(function=5, address=address, value=value):
            return (ParamValue(address, raw=int(value == COIL_ON), value=int(value == COIL_ON)),)
        case WriteSingle(address=address, value=value):
            return (ParamValue(address, raw=value, value=value),)
        case WriteRegistersRequest(address=address, values=values):
            return tuple(ParamValue(address + i, raw=v, value=v) for i, v in enumerate(values))
        case WriteCoilsRequest(address=address, bits=bits):
            return tuple(ParamValue(address + i, raw=int(b), value=int(b)) for i, b in enumerate(bits))
        case ReadWriteRequest():
            written = tuple(ParamValue(pdu.write_address + i, raw=v, value=v) for i, v in enumerate(pdu.values))
            return written + tuple(ParamValue(pdu.read_address + i) for i in range(pdu.read_count))
        case MaskWrite(address=address):
            return (ParamValue(address),)
    return ()


def adu(body: bytes) -> bytes:
    return body + crc_bytes(body)


@st.composite
def exchanges(draw: st.DrawFn) -> tuple[bytes, bytes]:
    """A request and an answer of the functions that name registers or coils, counts and
    addresses anywhere (past what Modbus allows, past address 65535)."""
    function = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 15, 16, 22, 23]))
    address, count = draw(st.integers(0, 0xFFFF)), draw(st.integers(0, 2100))
    payload = draw(st.binary(min_size=0, max_size=40))
    head = bytes([7, function])
    if function in (1, 2, 3, 4):
        return adu(head + struct.pack(">HH", address, count)), adu(head + bytes([len(payload)]) + payload)
    if function in (5, 6):
        single = adu(head + struct.pack(">H", address) + draw(st.sampled_from([b"\xff\x00", b"\x00\x00"]) | st.binary(
            min_size=2, max_size=2)))
        return single, single
    if function == 22:
        return adu(head + struct.pack(">HHH", address, 0xFF00, 0x0011)), adu(head + struct.pack(">HHH", address, 1, 2))
    if function == 23:
        request = head + struct.pack(">HHHHB", address, count, draw(st.integers(0, 0xFFFF)), len(payload) // 2,
                                     len(payload) // 2 * 2) + payload[: len(payload) // 2 * 2]
        return adu(request), adu(head + bytes([len(payload)]) + payload)
    return adu(head + struct.pack(">HHB", address, count, len(payload)) + payload), \
        adu(head + struct.pack(">HH", address, count))


@given(exchanges())
def test_runs_name_what_the_plain_rule_names(exchange: tuple[bytes, bytes]) -> None:
    request = parse_pdu(exchange[0], is_request=True)
    answer = parse_pdu(exchange[1], is_request=False)
    for pdu, asked in ((request, None), (answer, request)):
        assert expand_runs(param_runs(pdu, asked)) == reference_params(pdu, asked)
