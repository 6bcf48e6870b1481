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
"""

from __future__ import annotations

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
