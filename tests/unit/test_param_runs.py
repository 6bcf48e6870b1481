"""Params as runs (the columnar form) against params one object each (the plain path): the
same registers, the same JSON text, the same numeric values, for any frame."""

from __future__ import annotations

import json
import struct

from hypothesis import given
from hypothesis import strategies as st

from decoders.crc import crc_bytes
from decoders.message import Decoding, ParamValue
from decoders.modbus.param_runs import LazyParams, ParamRun, expand_runs, param_runs
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
from decoders.modbus.pdu_parse import parse_pdu
from sniffer.encoding.param_text import param_record, runs_json
from sniffer.exports.mcap_export import numeric_params


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


@given(exchanges())
def test_outputs_write_runs_as_they_write_params(exchange: tuple[bytes, bytes]) -> None:
    """The JSONL text and the MCAP numeric values of a decoding without a profile, from its
    runs, are what the plain path makes of its params."""
    request = parse_pdu(exchange[0], is_request=True)
    answer = parse_pdu(exchange[1], is_request=False)
    for pdu, asked in ((request, None), (answer, request)):
        lazy = LazyParams("s", pdu, asked)
        plain = Decoding("s", params=reference_params(pdu, asked), pdu=pdu)
        expected = json.dumps([param_record(p) for p in plain.params], separators=(",", ":"))
        assert runs_json(lazy.runs).decode() == expected
        assert numeric_params(lazy) == numeric_params(plain)
        assert list(numeric_params(lazy)) == list(numeric_params(plain))


@given(st.lists(st.tuples(st.integers(0, 0x1_0100), st.integers(0, 130), st.booleans(), st.integers(0, 0xFFFF)),
                max_size=4))
def test_runs_text_anywhere_in_the_address_space(drawn: list[tuple[int, int, bool, int]]) -> None:
    runs = tuple(ParamRun(address, count, [(value + i) & 0xFFFF for i in range(count)] if valued else None)
                 for address, count, valued, value in drawn)
    expected = [param_record(p) for p in expand_runs(runs)]
    assert json.loads(runs_json(runs)) == expected
    assert runs_json(runs).decode() == json.dumps(expected, separators=(",", ":"))
