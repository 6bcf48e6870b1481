"""The texts of a frame record's ``params``: JSON per param, and tables for unnamed ones.

For registers no profile names every param record is the same text but for the address and the
value. Each address's start (``,{"address":…,"raw":``) and each value's end (``…,"unit":null}``)
is formatted once, in two tables of 65 536 (built at first use, 5 MB each), from which
the frames in columns are spelt (:mod:`sniffer.encoding.decoded_texts`). Raw values are 16-bit
words or coil bits, so a value is its own index. A named param's JSON is made once per param
(:data:`PARAM_JSON`). Exactly the JSON of :func:`param_record` (the tests compare both).
"""

from __future__ import annotations

import json
import math
from typing import Any

import orjson

from decoders.memo import KeptByIdentity
from decoders.message import ParamValue

#: The end of a param record without a value (a read request names registers without).
NO_VALUE_END = b'null,"value":null,"unit":null}'
WORDS = 1 << 16

_starts: list[bytes] = []
_value_ends: list[bytes] = []


def param_tables() -> tuple[list[bytes], list[bytes]]:
    """The two tables, by address and by value (each entry's text: see the module docstring),
    built at first use."""
    if not _starts:
        _starts.extend(map(param_start, range(WORDS)))
        _value_ends.extend(b'%d,"value":%d,"unit":null}' % (value, value) for value in range(WORDS))
    return _starts, _value_ends


def param_start(address: int) -> bytes:
    """A param's text up to its raw value, after a comma."""
    return b',{"address":%d,"code":null,"name":null,"raw":' % address


def encode_record(record: dict[str, Any]) -> str:
    """One record as compact JSON, exactly what ``json.dumps`` writes with
    ``separators=(",", ":")`` and ``ensure_ascii=False`` (scripts compare outputs)."""
    return json.dumps(record, ensure_ascii=False, separators=(",", ":"))


def encode_json(value: object) -> bytes:
    """Compact UTF-8 JSON, fast (orjson), where no one compares bytes (MCAP messages).
    Numbers may be spelt differently from ``json.dumps``: ``0.00005`` for ``5e-05``.
    A copy: orjson's own bytes object keeps the 4 KiB buffer it wrote into, and the records'
    caches keep tens of thousands of texts (the copy costs 50 ns; holding orjson's took
    260 MB more on 1 M mixed frames)."""
    return bytes(memoryview(orjson.dumps(value)))


def _spelt_alike(param: ParamValue) -> bool:
    """Whether orjson writes the param's numbers as ``json.dumps`` does: floats differ only
    where ``repr`` switches to an exponent."""
    value = param.value
    return type(value) is not float or value == 0 or 1e-4 <= abs(value) < 1e16


def json_value(value: object) -> object:
    """A param's value as JSON holds it: a NaN or infinite float is ``null`` (JSON has no such
    number; the raw bits say what it was)."""
    return None if type(value) is float and not math.isfinite(value) else value


def param_record(param: ParamValue) -> dict[str, Any]:
    """A param's JSON record: a value over several registers adds their ``words``; a float that
    is NaN or infinite is ``null`` (JSON has no such number; ``raw`` and ``words`` keep it)."""
    record = {
        "address": param.address,
        "code": param.code,
        "name": param.name,
        "raw": param.raw,
        "value": json_value(param.value),
        "unit": param.unit,
    }
    if param.words is not None:
        record["words"] = list(param.words)
    return record


def param_json(param: ParamValue) -> bytes:
    """``param``'s JSON in a frame record (a profiled param: :func:`param_record`)."""
    record = param_record(param)
    return encode_json(record) if _spelt_alike(param) else encode_record(record).encode()


def member_json(param: ParamValue) -> bytes:
    """``param`` as a member of a ``/slave/N/params`` message after a comma (the MCAP export's
    members: by code, or by address where none names it; a state word's raw value);
    ``b""`` where it carries no reading (no raw value, or a marker)."""
    if not param.reading:
        return b""
    key = param.code if param.code is not None else str(param.address)
    value = param.value if isinstance(param.value, int | float) else param.raw
    return b"," + encode_json({key: value})[1:-1]


#: Each profiled param's JSON in a frame record, and its ``/slave/N/params`` member.
PARAM_JSON: KeptByIdentity[ParamValue, bytes] = KeptByIdentity(param_json)
PARAM_MEMBERS: KeptByIdentity[ParamValue, bytes] = KeptByIdentity(member_json)
