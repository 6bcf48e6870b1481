"""Values of one or more registers as a device means them: the types and the word orders.

A Modbus register is one 16-bit word. Devices put wider quantities in consecutive registers
and say in their register maps how: the type (``u32``, ``f32``, ...) and which word comes
first. One function reads them all (:func:`read_values`), for the profiles' parameters and
for ``--registers`` alike (:mod:`decoders.profiles.naming`).

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

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


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


def read_values(kind: ValueType, order: str, words: npt.NDArray[np.int64]) -> tuple[
        list[int | None], list[int | float | str]]:
    """The values of ``words`` (a row per value: its registers' words in address order) as
    ``kind`` in ``order``, and their raw bits as one unsigned number each (``None`` for a
    string: text has no number). All at once: a bus of meters reports new floats by the hundred
    thousand."""
    laid = laid_out(words, order)
    if not kind.code:
        texts: list[int | float | str] = [row.tobytes().rstrip(b"\x00").decode("latin-1") for row in laid]
        return [None] * len(texts), texts
    size = 2 * kind.registers
    raws: list[int | None] = laid.view(f">u{size}").ravel().tolist()
    numbers = laid.view(f">{'f' if kind.floating else _INTEGERS[kind.code]}{size}").ravel()
    digits = FLOAT_DIGITS.get(kind.code)
    if digits is None:
        return raws, numbers.tolist()
    with np.errstate(invalid="ignore"):  # a signalling NaN is a NaN here
        floats = numbers.astype(np.float64)
    return raws, significant(floats, digits).tolist()


def laid_out(words: npt.NDArray[np.int64], order: str) -> npt.NDArray[np.uint16]:
    """Each row of ``words`` (registers in address order) as its value's bytes lie, the most
    significant first (``order``: one of :data:`ORDERS`), as big-endian 16-bit words."""
    laid: npt.NDArray[np.uint16] = words.astype(">u2")
    if order in ("little", "little-swap"):
        laid = np.ascontiguousarray(laid[:, ::-1])
    if order.endswith("-swap"):
        laid = laid.byteswap()
    return laid


#: A float64 holds 17 significant digits: rounded to as many, it is itself.
_EXACT_DIGITS = 17


def significant(numbers: npt.NDArray[np.float64], digits: int) -> npt.NDArray[np.float64]:
    """``numbers`` rounded to ``digits`` significant digits (NaN, infinities and 0 as they are),
    exactly as ``float(f"{number:.7g}")`` rounds one. An ``f32``'s value (24 bits of mantissa)
    whose decimal exponent is -6 to 21 is rounded by numpy, the numbers of each exponent at
    once: times 10**k (k <= 12) its product is exact, and 10**k (k <= 22) is a double, so that
    ``np.round`` meets the decimal rounding; any other number is formatted."""
    if digits >= _EXACT_DIGITS:
        return numbers
    finite = np.isfinite(numbers) & (numbers != 0)
    size = np.abs(np.where(finite, numbers, 1.0))
    exponent = np.floor(np.log10(size)).astype(np.int64)
    with np.errstate(over="ignore"):  # 10**309 is inf, and so is a double past an f32's range
        exponent += size >= 10.0 ** (exponent + 1)  # log10 a hair off at a power of ten
        exponent -= size < 10.0 ** exponent
        single = numbers.astype(np.float32).astype(np.float64) == numbers
    exact = finite & single & (exponent >= -_MOST_DECIMALS + digits - 1) & (exponent <= _MOST_POWER) & (
        digits == _SINGLE_DIGITS)
    rounded = numbers.copy()
    for place in np.unique(exponent[exact]).tolist():
        chosen = exact & (exponent == place)
        rounded[chosen] = np.round(numbers[chosen], digits - 1 - place)
    others = np.flatnonzero(finite & ~exact)
    if len(others):
        rounded[others] = [float(f"{number:.{digits}g}") for number in numbers[others].tolist()]
    return rounded


#: The significant digits of an ``f32``; the most decimals by which numpy's rounding of one is
#: exact (its 24-bit mantissa times 5**12 fits a double's 53 bits); the largest power of ten a
#: double holds exactly.
_SINGLE_DIGITS, _MOST_DECIMALS, _MOST_POWER = 7, 12, 22

#: numpy's kind letter of each integer :mod:`struct` code.
_INTEGERS = {"H": "u", "h": "i", "I": "u", "i": "i", "Q": "u", "q": "i"}
