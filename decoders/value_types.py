"""Values of one or more registers as a device means them: the types and the word orders.

A Modbus register is one 16-bit word. Devices put wider quantities in consecutive registers
and say in their register maps how: the type (``u32``, ``f32``, ...) and which word comes
first. One function reads them all (:func:`read_value`), for the profiles' parameters
(:mod:`decoders.profiles.naming`) and for ``--registers`` (:mod:`decoders.register_format`).

Types: ``u16`` ``i16`` (one register), ``u32`` ``i32`` ``f32`` (two), ``u64`` ``i64`` ``f64``
(four), integers unsigned or two's complement and floats IEEE 754; ``string``: text over any
number of registers, two characters a register, trailing NULs dropped (as pymodbus reads them).

Orders, writing the value's bytes A B C D … from the most significant:

| order | registers on the wire | who uses it |
|---|---|---|
| ``big`` | AB CD: high word first | Modbus's own byte order carried on (the default) |
| ``little`` | CD AB: low word first | many PLCs: Schneider XBT ``%MD``/``%MF``, Modicon |
| ``big-swap`` | BA DC: high word first, each word's bytes swapped | some meters and gateways |
| ``little-swap`` | DC BA: low word first, bytes swapped (little-endian byte by byte) | x86-based devices |

A string's first character is the high byte of its first register under ``big``, the low byte
under ``big-swap``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class ValueType:
    """How a type reads its registers: ``registers`` (0: a string sets its own),
    ``code``, its :mod:`struct` code (``""``: text)."""

    name: str
    registers: int
    code: str

    @property
    def number(self) -> bool:
        return bool(self.code)

    @property
    def floating(self) -> bool:
        return self.code in ("f", "d")


TYPES: dict[str, ValueType] = {kind.name: kind for kind in (
    ValueType("u16", 1, "H"), ValueType("i16", 1, "h"),
    ValueType("u32", 2, "I"), ValueType("i32", 2, "i"), ValueType("f32", 2, "f"),
    ValueType("u64", 4, "Q"), ValueType("i64", 4, "q"), ValueType("f64", 4, "d"),
    ValueType("string", 0, ""),
)}
ORDERS = ("big", "little", "big-swap", "little-swap")
#: A string holds at most this many registers (a Modbus read carries 125).
MOST_STRING_REGISTERS = 125
#: Significant digits of a float as the device's type holds it: an f32 read as 22.936493…
#: says 22.93649 (what the device can mean), an f64 all that ``repr`` writes.
FLOAT_DIGITS = {"f": 7, "d": 17}


def value_bytes(words: Sequence[int], order: str) -> bytes:
    """The value's bytes, most significant first, from its registers as they came (``order``:
    one of :data:`ORDERS`)."""
    ordered = words if order in ("big", "big-swap") else words[::-1]
    data = struct.pack(f">{len(ordered)}H", *ordered)
    if order.endswith("-swap"):
        swapped = bytearray(data)
        swapped[0::2], swapped[1::2] = data[1::2], data[0::2]
        return bytes(swapped)
    return data


def read_value(kind: ValueType, words: Sequence[int], order: str) -> tuple[int | None, int | float | str]:
    """The value of ``words`` (the registers of one quantity, in address order) as ``kind`` in
    ``order``, and its raw bits as one unsigned number (``None`` for a string: text has no
    number)."""
    data = value_bytes(words, order)
    if not kind.code:
        return None, data.rstrip(b"\x00").decode("latin-1")
    raw = int.from_bytes(data, "big")
    if kind.floating:
        value: float = struct.unpack(f">{kind.code}", data)[0]
        return raw, float(f"{value:.{FLOAT_DIGITS[kind.code]}g}") if math.isfinite(value) else value
    number: int = struct.unpack(f">{kind.code}", data)[0]
    return raw, number

