"""``rtusniff profiles import MAP.csv``: a profile from a register map.

Vendors publish register maps and users keep them in spreadsheets: a row a register, columns
named in a header row. This reads such a table saved as CSV (comma, semicolon or tab; UTF-8,
with or without Excel's byte-order mark) into a checked profile:

* **Columns** are found by their header, whatever its case and punctuation
  (:data:`HEADERS`): an address and a name are needed; code, unit, scale, type, word order,
  access, registers (a string's length) and table (holding register, coil, …) are read where
  present. A code missing is made from the name (``Flow rate`` → ``FLOW_RATE``).
* **Addresses**: a number, decimal or hexadecimal (``0x0C81``, ``0C81h``). Modicon references
  (``40001``-``49999`` and ``400001``-``465536`` holding registers, ``3xxxx`` input registers,
  ``0xxxx`` coils, ``1xxxx`` discrete inputs) are recognised where every address of the map is
  one, and say the table too; other numbers are addresses as sent (from 0). ``--addressing``
  says it instead: ``wire`` (from 0), ``1`` (from 1, as many manuals count), ``4x``
  (references). What was assumed is said on standard error.
* **Types** and **word orders** in the words maps use (``FLOAT``, ``REAL``, ``Float32``,
  ``DINT``, ``UINT32``, ``CDAB``, ``low word first``, …: :data:`TYPE_WORDS`, :data:`ORDER_WORDS`).

A row that cannot be read is one line naming its row and column; any such row, and nothing is
written (exit 12). Rows that hold one cell (a section's title) are skipped, and said.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

from decoders.value_types import MOST_STRING_REGISTERS, TYPES
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.profile_text import Entry, Value, checked_profile_text, profile_text

#: Our field → the headers that name it (lower case, letters and digits only).
HEADERS: dict[str, tuple[str, ...]] = {
    "address": ("address", "addr", "register", "reg", "modbusaddress", "registeraddress", "regaddress", "offset",
                "pduaddress", "modbusregister", "registernumber", "regno"),
    "code": ("code", "tag", "symbol", "short", "shortname", "mnemonic", "abbreviation", "id"),
    "name": ("name", "description", "desc", "parameter", "parametername", "label", "signal", "variable",
             "designation"),
    "unit": ("unit", "units", "uom", "engineeringunit", "engineeringunits"),
    "scale": ("scale", "factor", "multiplier", "gain", "scaling", "scalefactor", "resolution"),
    "type": ("type", "datatype", "format", "dtype", "valuetype", "datatyp"),
    "word_order": ("wordorder", "order", "byteorder", "endianness", "endian", "swap", "wordswap"),
    "access": ("access", "rw", "readwrite", "mode", "permission", "accessright"),
    "registers": ("registers", "length", "size", "count", "words", "quantity", "numberofregisters"),
    "table": ("table", "function", "fc", "registertype", "objecttype", "area", "datatable"),
}
#: Words of the type column (lower case, letters and digits only) → our type (``bool``: a coil).
TYPE_WORDS: dict[str, str] = {
    **{word: "u16" for word in ("u16", "uint16", "unsigned", "unsigned16", "word", "uint", "ushort", "unsignedshort")},
    **{word: "i16" for word in ("i16", "int16", "s16", "signed", "signed16", "int", "short", "integer", "sint16")},
    **{word: "u32" for word in ("u32", "uint32", "dword", "udint", "ulong", "unsigned32", "unsignedlong")},
    **{word: "i32" for word in ("i32", "int32", "s32", "dint", "long", "signed32", "sint32")},
    **{word: "f32" for word in ("f32", "float", "float32", "real", "single", "ieee754", "ieeefloat", "fp32")},
    **{word: "u64" for word in ("u64", "uint64", "ulint", "unsigned64", "qword")},
    **{word: "i64" for word in ("i64", "int64", "lint", "signed64", "longlong")},
    **{word: "f64" for word in ("f64", "double", "float64", "lreal", "fp64")},
    **{word: "string" for word in ("string", "str", "ascii", "char", "chars", "text")},
    **{word: "bool" for word in ("bool", "boolean", "bit", "coil", "binary", "digital")},
}
ORDER_WORDS: dict[str, str] = {
    **{word: "big" for word in ("big", "bigendian", "abcd", "highfirst", "highwordfirst", "mswfirst", "msw",
                                "normal", "noswap", "be", "1234")},
    **{word: "little" for word in ("little", "littleendian", "cdab", "lowfirst", "lowwordfirst", "lswfirst", "lsw",
                                   "wordswap", "swapped", "swap", "3412")},
    **{word: "big-swap" for word in ("bigswap", "badc", "byteswap", "2143")},
    **{word: "little-swap" for word in ("littleswap", "dcba", "4321")},
}
ACCESS_WORDS: dict[str, str] = {
    **{word: "r" for word in ("r", "ro", "read", "readonly", "rd")},
    **{word: "w" for word in ("w", "wo", "write", "writeonly")},
    **{word: "rw" for word in ("rw", "readwrite", "wr", "all")},
}
TABLE_WORDS: dict[str, str] = {
    **{word: "parameter" for word in ("holding", "holdingregister", "holdingregisters", "hr", "4x", "3", "6", "16",
                                      "inputregister", "inputregisters", "ir", "3x", "4")},
    **{word: "coil" for word in ("coil", "coils", "0x", "1", "5", "15", "do", "digitaloutput")},
    **{word: "input" for word in ("discreteinput", "discreteinputs", "di", "1x", "2", "input", "digitalinput")},
}
#: Modicon references: the first digit's table, and its first number.
_REFERENCES = {"4": ("parameter", 40001), "3": ("parameter", 30001), "0": ("coil", 1), "1": ("input", 10001)}
_HEX = re.compile(r"^(?:0x([0-9a-f]+)|([0-9a-f]+)h)$")


def _word(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", text.lower())


@dataclass
class ImportedMap:
    """The profile's text, and what was assumed or skipped (said on standard error)."""

    text: str
    said: list[str]


class _Rows:
    """The map's rows as dictionaries by our field, and the faults found, a line each."""

    def __init__(self, path: str, rows: list[list[str]]) -> None:
        self.path = path
        self.faults: list[str] = []
        self.columns = self._columns(rows[0])
        self.rows = rows[1:]

    def _columns(self, header: list[str]) -> dict[str, int]:
        found: dict[str, int] = {}
        for place, title in enumerate(header):
            word = _word(title)
            field = next((name for name, words in HEADERS.items() if word in words), None)
            if field is not None and field not in found:
                found[field] = place
        missing = [name for name in ("address", "name") if name not in found]
        if missing:
            raise RtuSniffError(ErrorKind.BAD_PROFILE, f"row 1 (the header): no column of {' or '.join(missing)} "
                                f"(headers: {', '.join(repr(h) for h in header[:12])}); name them, e.g. "
                                "'Address' and 'Name'", path=self.path)
        return found

    def cell(self, row: list[str], field: str) -> str:
        place = self.columns.get(field)
        return "" if place is None or place >= len(row) else row[place].strip()

    def read(self, number: int, row: list[str], field: str, words: dict[str, str], wanted: str) -> str | None:
        """The field's cell as one of ``words`` means it (``None``: empty, or a fault, noted)."""
        text = self.cell(row, field)
        if not text:
            return None
        found = words.get(_word(text))
        if found is None:
            self.fault(number, field, f"{text!r} is not {wanted}")
        return found

    def fault(self, number: int, field: str, message: str) -> None:
        header = self.columns.get(field)
        column = "" if header is None else f", column {_column_name(header)}"
        self.faults.append(f"{self.path}: row {number}{column} ({field}): {message}")


def _column_name(place: int) -> str:
    """A spreadsheet's column letters (0 → A, 26 → AA)."""
    letters = ""
    place += 1
    while place:
        place, rest = divmod(place - 1, 26)
        letters = chr(ord("A") + rest) + letters
    return letters


def read_rows(path: str) -> list[list[str]]:
    """The CSV's rows (its delimiter sniffed); errors name the file."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "no such register map", path=path) from None
    except OSError as exc:
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, f"byte {exc.start} is not UTF-8: save the map as CSV UTF-8",
                            path=path) from None
    if "\0" in text:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, "holds NUL bytes: not a CSV text (an .xlsx? save it as CSV)",
                            path=path)
    try:
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(text[:8192], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    rows = [row for row in csv.reader(io.StringIO(text), dialect) if any(cell.strip() for cell in row)]
    if len(rows) < 2:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, "has no rows under its header", path=path)
    return rows


#: ``--addressing`` of ``profiles import``: found from the map, or said.
MAP_ADDRESSINGS = ("auto", "wire", "1", "4x")


def import_map(path: str, *, profile_id: str, name: str, addressing: str, word_order: str | None) -> ImportedMap:
    """The profile of the register map at ``path`` (see the module docstring)."""
    table = _Rows(path, read_rows(path))
    # A row of one cell is a section's title, or a lone note: no register.
    titles = {number for number, row in enumerate(table.rows, 2) if sum(bool(cell.strip()) for cell in row) <= 1}
    addresses = [(number, table.cell(row, "address")) for number, row in enumerate(table.rows, 2)
                 if number not in titles]
    rows = [row for number, row in enumerate(table.rows, 2) if number not in titles]
    references = _all_references([text for _, text in addresses if text]) if addressing in ("auto", "4x") else set()
    if addressing == "4x" and not references:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, "--addressing 4x: not every address is a Modicon reference "
                            "(40001, 30001, 00001, 10001, or six digits)", path=path)
    base = 1 if addressing == "1" else 0
    said = [f"addresses read as Modicon references ({', '.join(sorted(references))})" if references else
            "addresses read as counted from 1 (--addressing 1)" if base else
            "addresses read as sent on the wire, from 0" + ("" if addressing == "wire" else
                                                             " (--addressing 1 if the map counts from 1)")]
    entries: list[Entry] = []
    owners: dict[tuple[str, int], int] = {}
    codes: dict[str, int] = {}
    skipped = sorted(titles)
    for (number, address_text), row in zip(addresses, rows, strict=True):
        if not address_text:
            table.fault(number, "address", "is empty")
            continue
        entry = _entry(table, number, row, address_text, base=base, references=bool(references))
        if entry is None:
            continue
        _claim(table, number, entry, owners, codes)
        entries.append(entry)
    if skipped:
        said.append(f"skipped {len(skipped)} rows of one cell (titles?): {', '.join(map(str, skipped[:20]))}")
    if table.faults:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, "\n".join(table.faults[:200]) + (
            f"\n… and {len(table.faults) - 200} more" if len(table.faults) > 200 else "") + "\nnothing written")
    if not entries:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, "no register in the map", path=path)
    head: dict[str, Value | list[str]] = {"id": profile_id, "name": name,
                                          "sources": [f"register map {Path(path).name}"]}
    if word_order is not None:
        head["word_order"] = word_order
    comments = [f"Made by 'rtusniff profiles import' from {Path(path).name} ({len(entries)} rows); {said[0]}.",
                "Check it against the device: rtusniff profiles show FILE, and analyze a capture with it."]
    text = checked_profile_text(profile_text(head, entries, comments), path)
    return ImportedMap(text, said)


def _all_references(texts: list[str]) -> set[str]:
    """The tables of Modicon references where every address is one (else none)."""
    found = set()
    for text in texts:
        if not (text.isdigit() and (len(text) == 5 or (len(text) == 6 and text[0] in "4310"))):
            return set()
        kind, first = _REFERENCES.get(text[0], (None, 0))
        number = int(text[1:]) if len(text) == 6 else int(text) - first + 1
        if kind is None or number < 1 or number > 65536:
            return set()
        found.add({"parameter": "registers", "coil": "coils", "input": "discrete inputs"}[kind])
    return found


def _entry(table: _Rows, number: int, row: list[str], address_text: str, *, base: int,
           references: bool) -> Entry | None:
    """The row as an entry (``None``: a fault, noted)."""
    kind = "parameter"
    if references:
        kind, first = _REFERENCES[address_text[0]]
        address = int(address_text[1:]) - 1 if len(address_text) == 6 else int(address_text) - first
    else:
        parsed = _number(address_text)
        if parsed is None:
            table.fault(number, "address", f"{address_text!r} is no address (a number, or 0x0C81)")
            return None
        address = parsed - base
    if not 0 <= address <= 0xFFFF:
        table.fault(number, "address", f"{address_text!r} is outside the 65 536 addresses")
        return None
    named = table.cell(row, "table")
    if named:
        found = TABLE_WORDS.get(_word(named))
        if found is None:
            table.fault(number, "table", f"{named!r} is not a holding or input register, a coil or a discrete input")
            return None
        kind = found
    name = table.cell(row, "name")
    if not name:
        table.fault(number, "name", "is empty")
        return None
    keys: dict[str, Value] = {"address": address, "code": table.cell(row, "code") or _code(name, address),
                              "name": name}
    value_type = table.read(number, row, "type", TYPE_WORDS, "a type (u16, i32, float, …)")
    if value_type == "bool" and kind == "parameter":
        kind = "coil"
    if kind != "parameter":
        if value_type not in (None, "bool"):
            table.fault(number, "type", f"a {kind} is on or off, not {table.cell(row, 'type')!r}")
            return None
        return _with_access(table, number, row, Entry(kind, keys), kind)
    _parameter_keys(table, number, row, keys, value_type)
    return _with_access(table, number, row, Entry(kind, keys), kind)


def _parameter_keys(table: _Rows, number: int, row: list[str], keys: dict[str, Value], value_type: str | None) -> None:
    unit = table.cell(row, "unit")
    if unit and unit != "-":
        keys["unit"] = unit
    scale_text = table.cell(row, "scale")
    if scale_text:
        scale = _scale(scale_text)
        if scale is None:
            table.fault(number, "scale", f"{scale_text!r} is no factor (0.1, 1/10, 0,1)")
        elif scale != 1.0 and value_type != "string":
            keys["scale"] = scale
    if value_type is not None and value_type != "u16":
        keys["type"] = value_type
    if value_type == "string":
        count = _number(table.cell(row, "registers"))
        if count is None or not 1 <= count <= MOST_STRING_REGISTERS:
            table.fault(number, "registers", f"a string needs its registers, 1 to {MOST_STRING_REGISTERS}")
        else:
            keys["registers"] = count
    order = table.read(number, row, "word_order", ORDER_WORDS, "a word order (ABCD, CDAB, …)")
    if order is not None and (value_type in (None, "u16", "i16") or TYPES[value_type].registers == 1):
        order = None  # one register has no word order
    if order is not None:
        keys["word_order"] = order


def _with_access(table: _Rows, number: int, row: list[str], entry: Entry, kind: str) -> Entry:
    access = table.read(number, row, "access", ACCESS_WORDS, "r, w or rw")
    if access is not None and access != ("r" if kind == "input" else "rw"):
        entry.keys["access"] = access
    entry.keys["source"] = f"{Path(table.path).name} row {number}"
    return entry


def _claim(table: _Rows, number: int, entry: Entry, owners: dict[tuple[str, int], int], codes: dict[str, int]) -> None:
    """No register of a table in two rows, no code twice (a second one numbered)."""
    keys = entry.keys
    address = int(keys["address"])
    kind = str(keys.get("type", "u16"))
    size = int(keys.get("registers", TYPES[kind].registers if kind in TYPES else 1)) if entry.kind == "parameter" else 1
    for register in range(address, address + size):
        earlier = owners.setdefault((entry.kind, register), number)
        if earlier != number:
            table.fault(number, "address", f"register {register} is already row {earlier}'s")
            return
    code = str(keys["code"])
    if code in codes:
        keys["code"] = f"{code}_{number}"
    codes[str(keys["code"])] = number


def _number(text: str) -> int | None:
    word = text.strip().lower().replace("_", "")
    if word.isdigit():
        return int(word)
    found = _HEX.match(word)
    return None if found is None else int(found.group(1) or found.group(2), 16)


def _scale(text: str) -> float | None:
    word = text.strip().lower().lstrip("x×*").replace(" ", "")
    if "/" in word:
        top, _, bottom = word.partition("/")
        top_value, bottom_value = _scale(top), _scale(bottom)
        return None if top_value is None or not bottom_value else top_value / bottom_value
    try:
        value = float(word.replace(",", "."))
    except ValueError:
        return None
    return value if value and math.isfinite(value) else None


def _code(name: str, address: int) -> str:
    """A code made from a name: its words in capitals joined by ``_`` (at most 24 characters)."""
    code = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_").upper()[:24].rstrip("_")
    return code if code and not code.isdigit() else f"R{address}"

