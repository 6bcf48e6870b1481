"""The registers a frame names: within what Modbus allows, whatever a damaged count says."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from decoders.crc import crc_bytes
from decoders.modbus.codecs import parse_pdu
from decoders.modbus.codes import MAX_QUANTITY
from decoders.modbus.param_runs import named_registers


def request(slave: int, function: int, *words: int) -> bytes:
    body = bytes([slave, function]) + struct.pack(f">{len(words)}H", *words)
    return body + crc_bytes(body)


@pytest.mark.parametrize(("function", "limit"), sorted(MAX_QUANTITY.items()))
def test_a_request_for_more_than_modbus_allows_names_nothing(function: int, limit: int) -> None:
    """A bit flipped in the count of a read turned 'read 2' into 'read 9989': listing 9989
    registers would be noise (and memory); the summary says what is wrong instead."""
    adu = request(7, function, 1414, limit + 1)
    pdu = parse_pdu(adu, is_request=function < 15)
    assert named_registers(pdu, None) == ()
    assert f"({limit + 1}, Modbus allows 1..{limit})" in pdu.summary()


def test_a_read_at_the_limit_names_every_register() -> None:
    pdu = parse_pdu(request(7, 3, 1000, 125), is_request=True)
    params = named_registers(pdu, None)
    assert [p.address for p in params] == list(range(1000, 1125))
    assert pdu.summary() == "read HR 1000..1124 (125)"


def test_read_write_beyond_its_limits_names_nothing() -> None:
    body = bytes([7, 23]) + struct.pack(">HHHHBH", 12741, 126, 12761, 1, 2, 0x000F)  # read 126, write 1
    pdu = parse_pdu(body + crc_bytes(body), is_request=True)
    assert named_registers(pdu, None) == ()
    assert "(126, Modbus allows 1..125)" in pdu.summary()


@given(st.binary(min_size=2, max_size=60), st.booleans())
def test_no_frame_names_more_than_2000_registers_or_coils(body: bytes, is_request: bool) -> None:
    pdu = parse_pdu(body + crc_bytes(body), is_request=is_request)
    assert len(named_registers(pdu, None)) <= max(MAX_QUANTITY.values())
