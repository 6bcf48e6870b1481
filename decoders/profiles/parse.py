"""TOML text → :class:`Profile`, with every fault named by file and field.

Validation: required keys and their types, addresses 0-65535, no address or code
twice, every parameter and the profile itself citing a source, bit-field
references that exist, sane limits and indirection tables.
"""

from __future__ import annotations

import math
import tomllib
from typing import Any

from decoders.profiles.model import (
    Bit,
    BitField,
    ExceptionNote,
    Indirection,
    Limits,
    Parameter,
    Profile,
    Special,
    State,
)

ROLES = ("slave", "master")
ACCESS = ("r", "rw", "w")
ADDRESS_STYLES = ("plain", "xbt")
MAX_ADDRESS = 0xFFFF


class ProfileError(ValueError):
    """A profile that does not follow the format; the message names the place."""

    def __init__(self, origin: str, where: str, message: str) -> None:
        super().__init__(f"{origin}: {where}: {message}")


class _Reader:
    def __init__(self, origin: str) -> None:
        self.origin = origin

    def fail(self, where: str, message: str) -> ProfileError:
        return ProfileError(self.origin, where, message)

    def get(
        self, table: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str, default: Any = ...
    ) -> Any:
        if key not in table:
            if default is ...:
                raise self.fail(where, f"missing '{key}'")
            return default
        value = table[key]
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise self.fail(f"{where}.{key}", f"{value!r} is not {_kind_name(kind)}")
        return value

    def address(self, table: dict[str, Any], key: str, where: str) -> int:
        value: int = self.get(table, key, int, where)
        if not 0 <= value <= MAX_ADDRESS:
            raise self.fail(f"{where}.{key}", f"{value} is outside 0..65535")
        return value


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join({"str": "text", "int": "a whole number", "float": "a number", "list": "a list",
                        "dict": "a table", "bool": "true/false"}.get(k.__name__, k.__name__) for k in kinds)


def parse_profile(text: str, origin: str) -> Profile:
    """Parse and validate one profile; ``origin`` names it in errors."""
    reader = _Reader(origin)
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise reader.fail("TOML", str(exc)) from None
    head = reader.get(document, "profile", dict, "file")
    sources = tuple(reader.get(head, "sources", list, "profile"))
    if not sources or not all(isinstance(s, str) and s for s in sources):
        raise reader.fail("profile.sources", "cite at least one source (manual, section or page)")
    role = reader.get(head, "role", str, "profile", "slave")
    if role not in ROLES:
        raise reader.fail("profile.role", f"{role!r} is not one of {', '.join(ROLES)}")
    style = reader.get(head, "address_style", str, "profile", "plain")
    if style not in ADDRESS_STYLES:
        raise reader.fail("profile.address_style", f"{style!r} is not one of {', '.join(ADDRESS_STYLES)}")
    bitfields = _bitfields(reader, reader.get(document, "bitfield", dict, "file", {}))
    formula = reader.get(document, "address_formula", dict, "file", {})
    parameters = _parameters(reader, reader.get(document, "parameter", list, "file", []), bitfields, formula)
    return Profile(
        id=reader.get(head, "id", str, "profile"),
        name=reader.get(head, "name", str, "profile"),
        role=role,
        sources=sources,
        parameters=parameters,
        bitfields=bitfields,
        specials=tuple(_special(reader, s, f"special[{i}]") for i, s in enumerate(document.get("special", []))),
        exceptions=tuple(_exception(reader, e, f"exception[{i}]") for i, e in enumerate(document.get("exception", []))),
        limits=_limits(reader, reader.get(document, "limits", dict, "file", {})),
        indirections=tuple(
            _indirection(reader, t, f"indirection[{i}]") for i, t in enumerate(document.get("indirection", []))
        ),
        product_codes=tuple(reader.get(head, "product_codes", list, "profile", [])),
        address_style=style,
        notes=tuple(reader.get(head, "notes", list, "profile", [])),
        path=origin,
        **_uss_words(reader, reader.get(document, "uss", dict, "file", {}), bitfields),
    )


def _uss_words(reader: _Reader, table: dict[str, Any], bitfields: dict[str, BitField]) -> dict[str, str | None]:
    words: dict[str, str | None] = {}
    for key in ("control_word", "status_word"):
        name = reader.get(table, key, str, "uss", None)
        if name is not None and name not in bitfields:
            raise reader.fail(f"uss.{key}", f"no [bitfield.{name}] in this profile")
        words[f"uss_{key}"] = name
    return words


def _parameters(
    reader: _Reader, entries: list[Any], bitfields: dict[str, BitField], formula: dict[str, Any]
) -> dict[int, Parameter]:
    parameters: dict[int, Parameter] = {}
    codes: set[str] = set()
    for i, entry in enumerate(entries):
        where = f"parameter[{i}]"
        if not isinstance(entry, dict):
            raise reader.fail(where, "is not a table")
        code = reader.get(entry, "code", str, where)
        where = f"parameter {code}"
        address = _parameter_address(reader, entry, formula, where)
        if address in parameters:
            raise reader.fail(where, f"address {address} is already {parameters[address].code}")
        if code in codes:
            raise reader.fail(where, "code appears twice")
        bitfield = reader.get(entry, "bitfield", str, where, None)
        if bitfield is not None and bitfield not in bitfields:
            raise reader.fail(f"{where}.bitfield", f"no [bitfield.{bitfield}] in this profile")
        scale = float(reader.get(entry, "scale", (int, float), where, 1.0))
        if scale == 0 or not math.isfinite(scale):
            raise reader.fail(f"{where}.scale", "must be a finite number other than 0 (nan and inf are no scale)")
        access = reader.get(entry, "access", str, where, "rw")
        if access not in ACCESS:
            raise reader.fail(f"{where}.access", f"{access!r} is not one of {', '.join(ACCESS)}")
        codes.add(code)
        parameters[address] = Parameter(
            address=address,
            code=code,
            name=reader.get(entry, "name", str, where),
            source=_source(reader, entry, where),
            unit=reader.get(entry, "unit", str, where, None),
            scale=scale,
            signed=reader.get(entry, "signed", bool, where, False),
            access=access,
            enum=_enum(reader, reader.get(entry, "enum", dict, where, {}), f"{where}.enum"),
            bitfield=bitfield,
            note=reader.get(entry, "note", str, where, None),
        )
    return parameters


def _parameter_address(reader: _Reader, entry: dict[str, Any], formula: dict[str, Any], where: str) -> int:
    """``address`` directly, or ``number``/``index`` through the profile's address formula."""
    if "address" in entry:
        return reader.address(entry, "address", where)
    if "number" not in entry:
        raise reader.fail(where, "needs 'address' (or 'number' with an [address_formula])")
    if not formula:
        raise reader.fail(where, "has a parameter 'number' but the profile has no [address_formula]")
    number = reader.get(entry, "number", int, where)
    index = reader.get(entry, "index", int, where, 0)
    address: int = number * reader.get(formula, "multiplier", int, "address_formula") + index
    if not 0 <= address <= MAX_ADDRESS:
        raise reader.fail(where, f"number {number} index {index} gives address {address}, outside 0..65535")
    return address


def _source(reader: _Reader, entry: dict[str, Any], where: str) -> str:
    source: str = reader.get(entry, "source", str, where)
    if not source.strip():
        raise reader.fail(f"{where}.source", "cite where this comes from")
    return source


def _enum(reader: _Reader, table: dict[str, Any], where: str) -> dict[int, str]:
    values: dict[int, str] = {}
    for key, text in table.items():
        try:
            values[int(key, 0)] = str(text)
        except ValueError:
            raise reader.fail(where, f"key {key!r} is not a number") from None
    return values


def _bitfields(reader: _Reader, tables: dict[str, Any]) -> dict[str, BitField]:
    fields = {}
    for name, table in tables.items():
        where = f"bitfield.{name}"
        bits = tuple(
            Bit(
                bit=_bit_number(reader, b, f"{where}.bit[{i}]"),
                name=reader.get(b, "name", str, f"{where}.bit[{i}]"),
                set=reader.get(b, "set", str, f"{where}.bit[{i}]", None),
                clear=reader.get(b, "clear", str, f"{where}.bit[{i}]", None),
            )
            for i, b in enumerate(reader.get(table, "bit", list, where, []))
        )
        states = tuple(
            State(
                mask=reader.get(s, "mask", int, f"{where}.state[{i}]"),
                value=reader.get(s, "value", int, f"{where}.state[{i}]"),
                name=reader.get(s, "name", str, f"{where}.state[{i}]"),
            )
            for i, s in enumerate(reader.get(table, "state", list, where, []))
        )
        fields[name] = BitField(name, _source(reader, table, where), bits, states)
    return fields


def _bit_number(reader: _Reader, table: dict[str, Any], where: str) -> int:
    bit: int = reader.get(table, "bit", int, where)
    if not 0 <= bit <= 15:
        raise reader.fail(f"{where}.bit", f"{bit} is outside 0..15")
    return bit


def _special(reader: _Reader, table: dict[str, Any], where: str) -> Special:
    return Special(reader.get(table, "raw", int, where), reader.get(table, "meaning", str, where),
                   _source(reader, table, where))


def _exception(reader: _Reader, table: dict[str, Any], where: str) -> ExceptionNote:
    return ExceptionNote(
        code=reader.get(table, "code", int, where),
        explanation=reader.get(table, "explanation", str, where),
        source=_source(reader, table, where),
        function=reader.get(table, "function", int, where, 0),
        addresses=tuple(reader.get(table, "addresses", list, where, [])),
    )


def _limits(reader: _Reader, table: dict[str, Any]) -> Limits:
    where = "limits"
    numbers = {key: reader.get(table, key, int, where, 0) for key in
               ("read_registers", "write_registers", "read_write_read", "read_write_write")}
    for key, value in numbers.items():
        if not 0 <= value <= 125:
            raise reader.fail(f"{where}.{key}", f"{value} is outside 0..125")
    return Limits(
        functions=tuple(reader.get(table, "functions", list, where, [])),
        broadcast_functions=tuple(reader.get(table, "broadcast_functions", list, where, [])),
        **numbers,
    )


def _indirection(reader: _Reader, table: dict[str, Any], where: str) -> Indirection:
    count = reader.get(table, "count", int, where)
    defaults = tuple(reader.get(table, "defaults", list, where, [0] * count))
    if len(defaults) != count:
        raise reader.fail(f"{where}.defaults", f"has {len(defaults)} entries for {count} registers")
    return Indirection(
        prefix=reader.get(table, "prefix", str, where),
        address_registers=reader.address(table, "address_registers", where),
        value_registers=reader.address(table, "value_registers", where),
        count=count,
        defaults=defaults,
        source=_source(reader, table, where),
    )
