"""The test relay's absent slave (tests/ptylab.py): a request is dropped or passed whole, however
the pseudo-terminal splits it into reads."""

from __future__ import annotations

from pathlib import Path

from decoders.crc import crc_bytes
from tests.ptylab import Relay


def _request(slave: int) -> bytes:
    body = bytes([slave, 3, 0, 0, 0, 4])
    return body + crc_bytes(body)


def test_a_request_split_before_a_byte_that_names_an_absent_slave_is_passed_whole() -> None:
    relay = Relay(Path("master"), Path("slave"), absent=frozenset({9}))
    request = _request(1)
    assert request[-1] == 9  # 01 03 00 00 00 04 44 09: its CRC ends in the absent address
    assert [relay._absent(request[:7]), relay._absent(request[7:])] == [False, False]
    absent = _request(9)
    assert [relay._absent(absent[:2]), relay._absent(absent[2:])] == [True, True]
    assert relay._absent(_request(1)) is False  # the next request starts anew
