"""Hypothesis: the hand-written protobuf varints of ``foxglove.Log`` decode to the number written.

The encoder unrolls the common lengths (every timestamp's nanoseconds); a reference decoder of
the wire format checks every length, the boundaries between them and negative numbers, which
protobuf writes as ten-byte two's complement.
"""

from __future__ import annotations

from hypothesis import example, given
from hypothesis import strategies as st

from sniffer.exports.foxglove_log import _varint

BOUNDARIES = [(1 << bits) + delta for bits in range(7, 64, 7) for delta in (-1, 0)]


def _decode(data: bytes) -> int:
    value = 0
    for shift, byte in enumerate(data):
        value |= (byte & 0x7F) << (7 * shift)
        assert bool(byte & 0x80) == (shift < len(data) - 1), f"continuation bit wrong in {data.hex()}"
    return value


@given(st.one_of(st.integers(0, (1 << 64) - 1), st.sampled_from(BOUNDARIES)))
@example(0)
@example(999_999_999)
def test_varint_decodes_to_the_number(value: int) -> None:
    encoded = _varint(value)
    assert _decode(encoded) == value
    assert len(encoded) == max(1, -(-value.bit_length() // 7))


@given(st.integers(-(1 << 63), -1))
def test_negative_numbers_are_ten_bytes_of_twos_complement(value: int) -> None:
    encoded = _varint(value)
    assert len(encoded) == 10
    assert _decode(encoded) == value & ((1 << 64) - 1)
