"""How a profile names one register's value: the param record and its part of the summary.

The rules, value by value (the reference, :meth:`decoders.profiles.apply.ProfileApplier._param`,
applies them one call at a time):

- a register of a scanner table (:class:`~decoders.profiles.model.Indirection`) is named after
  its slot (``NM2``) and the parameter its address register points at (``NM2→RFRD``), or
  marked unassigned, or a copy of a register the profile does not know;
- otherwise the parameter at its address names it, or nothing does (XBT profiles still spell
  the address their way: ``%MW12``, ``40013``); a coil's or discrete input's (FC 1, 2, 5, 15)
  from the profile's coils or inputs, its value on (``True``) or off;
- a value a device reports that the profile lists as special (16#8000) is that meaning, not a
  reading (``available`` false, no unit); otherwise a parameter's value is its state or bit
  conditions, its enum text, or the raw word (signed where the parameter is) times its scale;
- a parameter over several registers (``f32``, ``string``: :mod:`decoders.value_types`) is one
  value where a frame carries all its registers, read in its word order and scaled (a float
  that is NaN or infinite is no reading: ``available`` false); a register of it without the
  others is that register alone, no value (``available`` false), and the frame says so in a
  remark (:meth:`AddressNamer.part_remark`);
- a parameter without a code (``--registers``: a type over registers, no name) types the
  value alone: the param has no code or name, the summary shows nothing of it, and no remark
  is made of a register left over (the user's guess covers every register).

What depends on the address alone (code, name, parameter, whether specials apply) is resolved
once per address by :class:`AddressNamer`; what depends on the raw word is made per value and
kept by the namer, since a drive reports the same values again and again. Drives of one profile
share its namers (sixteen drives report the same speeds), except at a scanner table's value
registers, whose meaning is each slave's own mapping.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from itertools import chain, repeat
from typing import cast

import numpy as np

from decoders.message import ParamValue
from decoders.profiles.model import Parameter, Profile
from decoders.value_types import FLOAT_DIGITS, TYPES, ValueType, read_values, significant

#: A named value: its param, and its part of the frame's summary (``None``: the summary leaves
#: it out, as it does values that are neither named nor a text).
NamedValue = tuple[ParamValue, str | None]
#: The summary names at most this many values, then says "…".
SHOWN_PARAMS = 12


class AddressNamer:
    """Names the values of one register (its scanner slot and target resolved), keeping each
    raw word's :data:`NamedValue` in :attr:`known` (its owner bounds their number)."""

    __slots__ = ("address", "code", "known", "learns", "name", "parameter", "profile", "specials", "word")

    def __init__(self, profile: Profile, address: int, label: tuple[str | None, str | None],
                 parameter: Parameter | None, *, reported: bool, learns: bool, word: int = 0) -> None:
        """``label``: the code and name (``None`` where nothing names the register);
        ``reported``: values from a device (specials apply); ``learns``: the register is a
        scanner table's address register (reading or writing it changes the table); ``word``:
        the register's place in its parameter (one over several registers)."""
        self.address = address
        self.code, self.name = label
        self.profile = profile
        self.parameter = parameter
        self.specials = profile.special_meanings if reported else {}
        #: By raw word; a parameter over several registers' values by their words (a tuple).
        self.known: dict[int | tuple[int | None, ...] | None, NamedValue] = {}
        self.learns = learns
        self.word = word

    @classmethod
    def of_bit(cls, profile: Profile, address: int, parameter: Parameter | None) -> AddressNamer:
        """The namer of a coil or discrete input (``parameter``: the profile's, if it names it)."""
        label = (None, None) if parameter is None else (parameter.code, parameter.name)
        return cls(profile, address, label, parameter, reported=False, learns=False)

    @property
    def registers(self) -> int:
        """How many registers its parameter's value takes (1 where none names it)."""
        return 1 if self.parameter is None else self.parameter.registers

    def make_values(self, values: list[tuple[int | None, ...]]) -> list[NamedValue]:
        """The values of a parameter over several registers (each: all its registers' raw words
        in address order, or ``None`` each where a request names them), named and kept: read
        all at once (:func:`~decoders.value_types.read_values`)."""
        parameter = self.parameter
        assert parameter is not None
        code, name, address, unit = self.code, self.name, self.address, parameter.unit
        kind = TYPES[parameter.type]
        carried = [words for words in values if words[0] is not None]  # all or none: the caller's rule
        size = parameter.registers
        raws, read = read_values(kind, parameter.word_order, np.fromiter(
            chain.from_iterable(carried), np.int64, size * len(carried)).reshape(len(carried), size)) if carried else (
            [], [])
        if parameter.scale != 1.0 and kind.number:
            read = _scaled(read, parameter.scale, kind)
        # A float that is NaN or infinite is no reading (a floating type reads floats only).
        valid: Iterable[bool] = list(map(math.isfinite, cast(list[float], read))) if kind.floating else repeat(True)
        # Built by map, not one call a value in Python: a bus of meters reports new floats by the thousand.
        params = list(map(ParamValue, repeat(address), repeat(code), repeat(name), raws, read, repeat(unit), valid,
                          carried))
        if len(carried) < len(values):  # a request's: no words
            found = iter(params)
            params = [ParamValue(address, code, name, None, None, unit) if words[0] is None else next(found)
                      for words in values]
        if code is None:
            named: list[NamedValue] = [(param, None) for param in params]
        elif kind.number and len(carried) == len(values):  # numbers as show() says them, formatted at once
            suffix = f" {unit}" if unit else ""
            named = list(zip(params, [f"{code} = {value}{suffix}" for value in read], strict=True))
        else:
            named = [(param, show(param)) for param in params]
        self.known.update(zip(values, named, strict=True))
        return named

    def make_part(self, raw: int | None) -> NamedValue:
        """One register of a parameter over several, without the others: the register alone,
        no value (kept)."""
        parameter = self.parameter
        assert parameter is not None
        param = ParamValue(self.address, self.code, self.name, raw, None, None, available=False)
        part = f"word {self.word + 1} of {parameter.registers}"
        shown = (None if self.code is None else f"{self.code} ({part})" if raw is None
                 else f"{self.code} = 16#{raw:04X} ({part})")
        named = self.known[raw] = (param, shown)
        return named

    def part_remark(self) -> str | None:
        """What a frame that names this register of a parameter over several, without the
        others, says of it (nothing of a parameter without a name: ``--registers``, a guess
        over every register, leaves a frame's last register over where it will)."""
        parameter = self.parameter
        assert parameter is not None
        if self.code is None:
            return None
        last = parameter.address + parameter.registers - 1
        return (f"register {self.address} is word {self.word + 1} of {parameter.registers} of {parameter.code} "
                f"({parameter.type} at {parameter.address}-{last}): one word alone is no value")

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


def _scaled(values: list[int | float | str], scale: float, kind: ValueType) -> list[int | float | str]:
    """Numbers times their parameter's scale (floats in the digits their type holds)."""
    if not kind.floating:
        return [value if isinstance(value, str) else round(value * scale, 6) for value in values]
    scaled: list[int | float | str] = significant(np.array(values, np.float64) * scale,
                                                  FLOAT_DIGITS[kind.code]).tolist()
    return scaled


def parameter_value(profile: Profile, parameter: Parameter,
                    raw: int | None) -> tuple[float | int | str | None, str | None]:
    """The value as the device means it, and its unit (for a raw word that is no marker)."""
    if raw is None:
        return None, parameter.unit
    if parameter.type == "bool":  # a coil or discrete input
        return raw == 1, None
    if parameter.bitfield is not None:
        return profile.bitfields[parameter.bitfield].describe(raw) or f"16#{raw:04X}", None
    if raw in parameter.enum:
        return parameter.enum[raw], None
    number = raw - 0x10000 if parameter.signed and raw & 0x8000 else raw
    if parameter.scale == 1.0:
        return number, parameter.unit
    return round(number * parameter.scale, 6), parameter.unit


def show(param: ParamValue) -> str:
    """A named value as the summary says it: ``LFR = 50.0 Hz``, ``ETA = 16#0637 ready``,
    ``SERIAL = "A1234"``."""
    label = param.code if param.code is not None else str(param.address)
    if param.raw is None:
        return f'{label} = "{param.value}"' if isinstance(param.value, str) else label
    if isinstance(param.value, str):
        return f"{label} = 16#{param.raw:04X} {param.value}"
    if isinstance(param.value, bool):
        return f"{label} = {'ON' if param.value else 'OFF'}"
    unit = f" {param.unit}" if param.unit else ""
    return f"{label} = {param.value}{unit}"


def summary_with(summary: str, shown: list[str]) -> str:
    """A frame's summary followed by its named values (``shown``: their texts, in order)."""
    if not shown:
        return summary
    more = " …" if len(shown) > SHOWN_PARAMS else ""
    return f"{summary}: {', '.join(shown[:SHOWN_PARAMS])}{more}"
