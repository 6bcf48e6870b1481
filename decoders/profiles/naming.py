"""How a profile names one register's value: the param record and its part of the summary.

The rules, value by value (the reference, :meth:`decoders.profiles.apply.ProfileApplier._param`,
applies them one call at a time):

- a register of a scanner table (:class:`~decoders.profiles.model.Indirection`) is named after
  its slot (``NM2``) and the parameter its address register points at (``NM2→RFRD``), or
  marked unassigned, or a copy of a register the profile does not know;
- otherwise the parameter at its address names it, or nothing does (XBT profiles still spell
  the address their way: ``%MW12``, ``40013``);
- a value a device reports that the profile lists as special (16#8000) is that meaning, not a
  reading (``available`` false, no unit); otherwise a parameter's value is its state or bit
  conditions, its enum text, or the raw word (signed where the parameter is) times its scale.

What depends on the address alone (code, name, parameter, whether specials apply) is resolved
once per address by :class:`AddressNamer`; what depends on the raw word is made per value and
kept by the namer, since a drive reports the same values again and again. Drives of one profile
share its namers (sixteen drives report the same speeds), except at a scanner table's value
registers, whose meaning is each slave's own mapping.

Where a register's values are plain numbers (no state word, enumeration or marker: a speed, a
current), an output that writes columns (the Parquet dataset) takes them as numbers in arrays
(:class:`PlainNumbers`, :class:`NumberNames`), each value the one :func:`parameter_value` gives,
looked up in a table of every raw word made by it once per scale: no param object per value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.message import ParamValue
from decoders.profiles.model import Parameter, Profile

#: A named value: its param, and its part of the frame's summary (``None``: the summary leaves
#: it out, as it does values that are neither named nor a text).
NamedValue = tuple[ParamValue, str | None]
#: The summary names at most this many values, then says "…".
SHOWN_PARAMS = 12


class AddressNamer:
    """Names the values of one register (its scanner slot and target resolved), keeping each
    raw word's :data:`NamedValue` in :attr:`known` (its owner bounds their number)."""

    __slots__ = ("address", "code", "known", "learns", "name", "parameter", "profile", "specials")

    def __init__(self, profile: Profile, address: int, label: tuple[str | None, str | None],
                 parameter: Parameter | None, *, reported: bool, learns: bool) -> None:
        """``label``: the code and name (``None`` where nothing names the register);
        ``reported``: values from a device (specials apply); ``learns``: the register is a
        scanner table's address register (reading or writing it changes the table)."""
        self.address = address
        self.code, self.name = label
        self.profile = profile
        self.parameter = parameter
        self.specials = profile.special_meanings if reported else {}
        self.known: dict[int | None, NamedValue] = {}
        self.learns = learns

    def plain_numbers(self) -> PlainNumbers | None:
        """How this register's plain numbers are named in arrays; ``None``: it has none (a state
        word, a bitfield). Made anew: its owner keeps it (``ProfileApplier.plain_numbers``)."""
        return _plain_numbers(self)

    def make(self, raw: int | None) -> NamedValue:
        """The value ``raw`` named (and kept in :attr:`known`)."""
        special = None if raw is None else self.specials.get(raw)
        parameter = self.parameter
        if parameter is None:
            param = ParamValue(self.address, self.code, self.name, raw, raw if special is None else special,
                               available=special is None)
        elif special is not None:
            # A marker (16#8000), not a reading: its meaning, no unit, not available.
            param = ParamValue(self.address, self.code, self.name, raw, special, None, available=False)
        else:
            value, unit = parameter_value(self.profile, parameter, raw)
            param = ParamValue(self.address, self.code, self.name, raw, value, unit)
        named = self.known[raw] = (param, show(param) if param.code is not None or type(param.value) is str else None)
        return named


@dataclass(frozen=True)
class PlainNumbers:
    """One register's values that are plain numbers: every raw word but ``words`` (markers,
    enumerated texts), each being ``value[raw]`` (:func:`parameter_value`); ``integral``: the
    values are whole (a scale of 1), written without a decimal point."""

    address: int
    code: str | None
    name: str | None
    unit: str | None
    integral: bool
    words: npt.NDArray[np.int64]
    value: npt.NDArray[np.float64]

    def param(self, raw: int, value: float) -> NamedValue:
        """The named value of ``raw`` (``value``: ``value[raw]``), as :meth:`AddressNamer.make` names it."""
        param = ParamValue(self.address, self.code, self.name, raw, int(value) if self.integral else value, self.unit)
        return param, None if self.code is None else show(param)


@dataclass(frozen=True)
class NumberNames:
    """Named values that are plain numbers, in columns: each entry's register (its place in
    ``registers``), raw word and value; the entries of a register lie together."""

    register: npt.NDArray[np.int64]
    raw: npt.NDArray[np.int64]
    value: npt.NDArray[np.float64]
    registers: list[PlainNumbers]

    def __len__(self) -> int:
        return len(self.raw)

    def objects(self) -> list[NamedValue]:
        """Each entry as a named value, as the register's namer names it."""
        registers = self.registers
        return [registers[register].param(raw, value) for register, raw, value in
                zip(self.register.tolist(), self.raw.tolist(), self.value.tolist(), strict=True)]


_RAW_WORDS = np.arange(0x10000, dtype=np.int64)
#: The values of every raw word, by (signed, scale): made once, by :func:`parameter_value`'s rule.
_SCALED: dict[tuple[bool, float], npt.NDArray[np.float64]] = {}


def _plain_numbers(namer: AddressNamer) -> PlainNumbers | None:
    parameter = namer.parameter
    if parameter is not None and parameter.bitfield is not None:
        return None
    words = {*namer.specials, *(() if parameter is None else parameter.enum)}
    signed, scale = (False, 1.0) if parameter is None else (parameter.signed, parameter.scale)
    values = _SCALED.get((signed, scale))
    if values is None:
        numbers = _RAW_WORDS - 0x10000 * ((_RAW_WORDS & 0x8000) != 0) if signed else _RAW_WORDS
        values = numbers.astype(np.float64) if scale == 1.0 else _rounded_products(numbers, scale)
        _SCALED[(signed, scale)] = values
    return PlainNumbers(namer.address, namer.code, namer.name, None if parameter is None else parameter.unit,
                        scale == 1.0, np.array(sorted(words), np.int64), values)


def _rounded_products(numbers: npt.NDArray[np.int64], scale: float) -> npt.NDArray[np.float64]:
    """``round(number * scale, 6)`` of each number, as Python rounds it, but by numpy: 1.4 ms
    for the 65 536 raw words against 34 ms a number at a time, which a short capture of a
    profiled drive paid at start for each sign and scale. Python rounds the exact value of the
    product to 6 decimals and takes the double nearest that decimal; numpy's ``rint`` of the
    product times 10⁶, divided by 10⁶ (exact integers, one correctly rounded division), is that
    double unless the product times 10⁶ lies within its rounding error of a half (or past exact
    integers): those few are rounded by Python (``tests/unit/test_plain_numbers.py``)."""
    products = numbers.astype(np.float64) * scale  # the product Python forms: the int made a double first
    shifted = products * 1e6
    values: npt.NDArray[np.float64] = np.rint(shifted) / 1e6
    near_half = np.abs(shifted - np.floor(shifted) - 0.5) <= 2 * np.spacing(np.abs(shifted))
    doubtful = np.flatnonzero(near_half | ~(np.abs(shifted) < 2.0**50))
    values[doubtful] = [round(number * scale, 6) for number in numbers[doubtful].tolist()]
    return values


def parameter_value(profile: Profile, parameter: Parameter,
                    raw: int | None) -> tuple[float | int | str | None, str | None]:
    """The value as the device means it, and its unit (for a raw word that is no marker)."""
    if raw is None:
        return None, parameter.unit
    if parameter.bitfield is not None:
        return profile.bitfields[parameter.bitfield].describe(raw) or f"16#{raw:04X}", None
    if raw in parameter.enum:
        return parameter.enum[raw], None
    number = raw - 0x10000 if parameter.signed and raw & 0x8000 else raw
    if parameter.scale == 1.0:
        return number, parameter.unit
    return round(number * parameter.scale, 6), parameter.unit


def show(param: ParamValue) -> str:
    """A named value as the summary says it: ``LFR = 50.0 Hz``, ``ETA = 16#0637 ready``."""
    label = param.code if param.code is not None else str(param.address)
    if param.raw is None:
        return label
    if isinstance(param.value, str):
        return f"{label} = 16#{param.raw:04X} {param.value}"
    unit = f" {param.unit}" if param.unit else ""
    return f"{label} = {param.value}{unit}"


def summary_with(summary: str, shown: list[str]) -> str:
    """A frame's summary followed by its named values (``shown``: their texts, in order)."""
    if not shown:
        return summary
    more = " …" if len(shown) > SHOWN_PARAMS else ""
    return f"{summary}: {', '.join(shown[:SHOWN_PARAMS])}{more}"
