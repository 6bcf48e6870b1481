"""TOML text → :class:`Profile`, with every fault named by file and field.

Validation: required keys and their types, addresses 0-65535, no address or code
twice, every parameter and the profile itself citing a source, bit-field
references that exist, sane limits and indirection tables.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterator
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
from decoders.value_types import MOST_STRING_REGISTERS, ORDERS, TYPES

ROLES = ("slave", "master")
ACCESS = ("r", "rw", "w")
ADDRESS_STYLES = ("plain", "xbt")
MAX_ADDRESS = 0xFFFF
#: A profile file is small: these bounds are checked before the TOML parser runs, so that a
#: hostile file (a key of 20 000 dotted parts, arrays nested 500 deep) is one error, not
#: gigabytes or a recursion error. Raise them here if a real profile ever needs more.
MAX_PROFILE_BYTES = 2**20
MAX_NESTING = 32
#: Registers an indirection names at most (a Modbus read carries at most 125).
MAX_INDIRECTION = 125


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
        if not _is(value, kind):
            raise self.fail(f"{where}.{key}", f"{_shown(value)} is not {_kind_name(kind)}")
        return value

    def tables(self, table: dict[str, Any], key: str, where: str) -> list[dict[str, Any]]:
        """An array of tables (``[[key]]``): a list whose every entry is a table."""
        entries: list[Any] = self.get(table, key, list, where, [])
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict):
                raise self.fail(f"{where}.{key}[{i}]", f"{_shown(entry)} is not a table")
        return entries

    def items(self, table: dict[str, Any], key: str, kind: type, where: str) -> tuple[Any, ...]:
        """A list whose every entry is of ``kind`` (whole numbers: not true/false)."""
        entries: list[Any] = self.get(table, key, list, where, [])
        for i, entry in enumerate(entries):
            if not _is(entry, kind):
                raise self.fail(f"{where}.{key}[{i}]", f"{_shown(entry)} is not {_kind_name(kind)}")
        return tuple(entries)

    def address(self, table: dict[str, Any], key: str, where: str) -> int:
        value: int = self.get(table, key, int, where)
        if not 0 <= value <= MAX_ADDRESS:
            raise self.fail(f"{where}.{key}", f"{value} is outside 0..65535")
        return value


def _is(value: Any, kind: type | tuple[type, ...]) -> bool:
    """Whether ``value`` is of ``kind``; a whole number is never true/false."""
    return isinstance(value, kind) and not (kind is int and isinstance(value, bool))


def _shown(value: Any) -> str:
    """A value as an error shows it: never more than a line."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:57]}..."


def _shape(reader: _Reader, text: str) -> None:
    """Refuse what no profile needs before the TOML parser sees it (see ``MAX_NESTING``)."""
    if len(text) > MAX_PROFILE_BYTES:
        raise reader.fail("file", f"is {len(text):,} characters; a profile has at most {MAX_PROFILE_BYTES:,}")
    nesting = _nesting(_outside_strings(text))
    if nesting > MAX_NESTING:
        raise reader.fail("file", f"nests {nesting} levels deep; a profile nests at most {MAX_NESTING}")


def _outside_strings(text: str) -> Iterator[str]:
    """The characters of ``text`` outside strings and comments (an approximation is enough
    here), a comment's or string's closing newline kept."""
    quoted = ""
    comment = escaped = False
    for char in text:
        if comment:
            comment = char != "\n"
            if not comment:
                yield char
        elif quoted:
            if escaped:
                escaped = False
            elif char == "\\" and quoted == '"':
                escaped = True
            elif char in (quoted, "\n"):
                quoted = ""
                if char == "\n":
                    yield char
        elif char == "#":
            comment = True
        elif char in "\"'":
            quoted = char
        else:
            yield char


def _nesting(chars: Iterator[str]) -> int:
    """How deep brackets nest, or how many parts a dotted key has (a.b.c = 1: counted until its
    own '=', so that a quoted "=" key before it hides nothing), whichever is more."""
    depth = deepest = dots = key_dots = 0
    in_value = False
    for char in chars:
        if char in "\n{,":  # a key may start here
            in_value, key_dots = False, 0
        if char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
        elif char == "=":
            in_value = True
        elif char == "." and not in_value:
            key_dots += 1
            dots = max(dots, key_dots)
    return max(deepest, dots)


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join({"str": "text", "int": "a whole number", "float": "a number", "list": "a list",
                        "dict": "a table", "bool": "true/false"}.get(k.__name__, k.__name__) for k in kinds)


def parse_profile(text: str, origin: str) -> Profile:
    """Parse and validate one profile; ``origin`` names it in errors."""
    reader = _Reader(origin)
    _shape(reader, text)
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise reader.fail("TOML", str(exc)) from None
    except RecursionError:  # what the shape check did not foresee
        raise reader.fail("file", f"nests too deep; a profile nests at most {MAX_NESTING}") from None
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
    order = _word_order(reader, head, "profile", "big")
    parameters = _parameters(reader, reader.tables(document, "parameter", "file"), bitfields, formula, order)
    coils, inputs = (_bits(reader, reader.tables(document, key, "file"), key) for key in ("coil", "input"))
    _codes_once(reader, [*parameters.values(), *coils.values(), *inputs.values()])
    return Profile(
        id=reader.get(head, "id", str, "profile"),
        name=reader.get(head, "name", str, "profile"),
        role=role,
        sources=sources,
        parameters=parameters,
        coils=coils,
        inputs=inputs,
        bitfields=bitfields,
        specials=tuple(_special(reader, s, f"special[{i}]") for i, s in enumerate(reader.tables(document, "special",
                                                                                                 "file"))),
        exceptions=tuple(_exception(reader, e, f"exception[{i}]")
                         for i, e in enumerate(reader.tables(document, "exception", "file"))),
        limits=_limits(reader, reader.get(document, "limits", dict, "file", {})),
        indirections=tuple(
            _indirection(reader, t, f"indirection[{i}]") for i, t in enumerate(reader.tables(document, "indirection",
                                                                                              "file"))
        ),
        product_codes=reader.items(head, "product_codes", str, "profile"),
        address_style=style,
        notes=reader.items(head, "notes", str, "profile"),
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
    reader: _Reader, entries: list[Any], bitfields: dict[str, BitField], formula: dict[str, Any], order: str
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
        kind, registers = _value_type(reader, entry, where)
        if registers > 1 or kind == "string":
            for key in ("enum", "bitfield", "signed"):
                if key in entry:
                    raise reader.fail(f"{where}.{key}", f"applies to a one-register type, not {kind}")
        if kind == "string" and "scale" in entry:
            raise reader.fail(f"{where}.scale", "a string has no scale")
        parameters[address] = Parameter(
            address=address,
            code=code,
            name=reader.get(entry, "name", str, where),
            source=_source(reader, entry, where),
            unit=reader.get(entry, "unit", str, where, None),
            scale=scale,
            signed=kind in ("i16", "i32", "i64"),
            access=access,
            enum=_enum(reader, reader.get(entry, "enum", dict, where, {}), f"{where}.enum"),
            bitfield=bitfield,
            note=reader.get(entry, "note", str, where, None),
            type=kind,
            registers=registers,
            word_order=_word_order(reader, entry, where, order),
        )
    _no_overlap(reader, parameters)
    return parameters


def _bits(reader: _Reader, entries: list[dict[str, Any]], key: str) -> dict[int, Parameter]:
    """``[[coil]]`` or ``[[input]]``: a coil or discrete input each, named; its value on or off."""
    found: dict[int, Parameter] = {}
    for i, entry in enumerate(entries):
        code = reader.get(entry, "code", str, f"{key}[{i}]")
        where = f"{key} {code}"
        address = reader.address(entry, "address", where)
        if address in found:
            raise reader.fail(where, f"address {address} is already {found[address].code}")
        unknown = sorted(set(entry) - {"address", "code", "name", "source", "note", "access"})
        if unknown:
            raise reader.fail(f"{where}.{unknown[0]}", f"a {key} has no '{unknown[0]}' (it is on or off)")
        access = reader.get(entry, "access", str, where, "rw" if key == "coil" else "r")
        if access not in ACCESS:
            raise reader.fail(f"{where}.access", f"{access!r} is not one of {', '.join(ACCESS)}")
        found[address] = Parameter(address, code, reader.get(entry, "name", str, where), _source(reader, entry, where),
                                   access=access, note=reader.get(entry, "note", str, where, None), type="bool")
    return found


def _codes_once(reader: _Reader, named: list[Parameter]) -> None:
    """No code names two things: the MCAP params message holds a frame's values by code."""
    seen: set[str] = set()
    for parameter in named:
        if parameter.code in seen:
            raise reader.fail(f"{'coil or input' if parameter.type == 'bool' else 'parameter'} {parameter.code}",
                              "code appears twice")
        seen.add(parameter.code)


def _value_type(reader: _Reader, entry: dict[str, Any], where: str) -> tuple[str, int]:
    """A parameter's type and how many registers it takes (``signed = true``: ``i16``)."""
    signed = reader.get(entry, "signed", bool, where, False)
    kind: str = reader.get(entry, "type", str, where, "i16" if signed else "u16")
    if kind not in TYPES:
        raise reader.fail(f"{where}.type", f"{kind!r} is not one of {', '.join(TYPES)}")
    if signed and kind != "i16":
        raise reader.fail(f"{where}.signed", f"says i16 where type says {kind}")
    if kind != "string":
        if "registers" in entry:
            raise reader.fail(f"{where}.registers", f"{kind} takes {TYPES[kind].registers}; only a string sets its own")
        return kind, TYPES[kind].registers
    registers: int = reader.get(entry, "registers", int, where)
    if not 1 <= registers <= MOST_STRING_REGISTERS:
        raise reader.fail(f"{where}.registers", f"{registers} is outside 1..{MOST_STRING_REGISTERS}")
    return kind, registers


def _word_order(reader: _Reader, table: dict[str, Any], where: str, default: str) -> str:
    order: str = reader.get(table, "word_order", str, where, default)
    if order not in ORDERS:
        raise reader.fail(f"{where}.word_order", f"{order!r} is not one of {', '.join(ORDERS)}")
    return order


def _no_overlap(reader: _Reader, parameters: dict[int, Parameter]) -> None:
    """No register belongs to two parameters (a parameter over several registers covers them)."""
    owner: dict[int, Parameter] = {}
    for parameter in sorted(parameters.values(), key=lambda p: (p.registers == 1, p.address)):
        for address in range(parameter.address, parameter.address + parameter.registers):
            if address > MAX_ADDRESS:
                raise reader.fail(f"parameter {parameter.code}", f"its {parameter.registers} registers end past 65535")
            if address in owner:
                raise reader.fail(f"parameter {parameter.code}",
                                  f"register {address} is already part of {owner[address].code}")
            owner[address] = parameter


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
        if not isinstance(table, dict):
            raise reader.fail(where, f"{_shown(table)} is not a table")
        bits = tuple(
            Bit(
                bit=_bit_number(reader, b, f"{where}.bit[{i}]"),
                name=reader.get(b, "name", str, f"{where}.bit[{i}]"),
                set=reader.get(b, "set", str, f"{where}.bit[{i}]", None),
                clear=reader.get(b, "clear", str, f"{where}.bit[{i}]", None),
            )
            for i, b in enumerate(reader.tables(table, "bit", where))
        )
        states = tuple(
            State(
                mask=reader.get(s, "mask", int, f"{where}.state[{i}]"),
                value=reader.get(s, "value", int, f"{where}.state[{i}]"),
                name=reader.get(s, "name", str, f"{where}.state[{i}]"),
            )
            for i, s in enumerate(reader.tables(table, "state", where))
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
        addresses=reader.items(table, "addresses", int, where),
    )


def _limits(reader: _Reader, table: dict[str, Any]) -> Limits:
    where = "limits"
    numbers = {key: reader.get(table, key, int, where, 0) for key in
               ("read_registers", "write_registers", "read_write_read", "read_write_write")}
    for key, value in numbers.items():
        if not 0 <= value <= 125:
            raise reader.fail(f"{where}.{key}", f"{value} is outside 0..125")
    return Limits(
        functions=reader.items(table, "functions", int, where),
        broadcast_functions=reader.items(table, "broadcast_functions", int, where),
        **numbers,
    )


def _indirection(reader: _Reader, table: dict[str, Any], where: str) -> Indirection:
    count = reader.get(table, "count", int, where)
    if not 1 <= count <= MAX_INDIRECTION:
        raise reader.fail(f"{where}.count", f"{count} is outside 1..{MAX_INDIRECTION}")
    defaults = reader.items(table, "defaults", int, where) if "defaults" in table else (0,) * count
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
