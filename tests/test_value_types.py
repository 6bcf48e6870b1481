"""Values over several registers: each type and word order read as pymodbus (independent code)
writes it, profiles that declare them, and every output of a real flow meter's floats."""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client.mixin import ModbusClientMixin

from decoders.crc import crc_bytes
from decoders.profiles.model import Parameter, Profile
from decoders.profiles.naming import AddressNamer, show
from decoders.profiles.parse import ProfileError, parse_profile
from decoders.value_types import TYPES, ValueType, read_values, significant
from tests.conftest import CliResult
from tests.real_recordings import TEXT, available

DATATYPE = ModbusClientMixin.DATATYPE
TO_PYMODBUS = {"i16": DATATYPE.INT16, "u16": DATATYPE.UINT16, "i32": DATATYPE.INT32, "u32": DATATYPE.UINT32,
               "f32": DATATYPE.FLOAT32, "i64": DATATYPE.INT64, "u64": DATATYPE.UINT64, "f64": DATATYPE.FLOAT64}
FLOWMETER = Path(__file__).parent / "data" / "flowmeter.toml"
METER = ("--profile-file", str(FLOWMETER), "--profile", "flowmeter")


def _numbers(kind: str) -> st.SearchStrategy[Any]:
    if kind.startswith("f"):
        return st.floats(width=32 if kind == "f32" else 64)
    bits = int(kind[1:])
    return st.integers(-(1 << bits - 1), (1 << bits - 1) - 1) if kind[0] == "i" else st.integers(0, (1 << bits) - 1)


def _swapped(words: list[int]) -> list[int]:
    return [((word & 0xFF) << 8) | (word >> 8) for word in words]


def read_value(kind: ValueType, words: list[int], order: str) -> tuple[int | None, int | float | str]:
    """One value read as the decoders read a batch of them."""
    raws, values = read_values(kind, order, np.array([words], np.int64))
    return raws[0], values[0]


@pytest.mark.parametrize("kind", list(TO_PYMODBUS))
@given(data=st.data())
def test_every_type_and_order_reads_what_pymodbus_writes(kind: str, data: st.DataObject) -> None:
    """pymodbus writes a number in big or little word order; read back in that order (and with
    each register's bytes swapped, in the ``-swap`` order) it is the number, ``raw`` its bits."""
    number = data.draw(_numbers(kind))
    for order in ("big", "little"):
        words = ModbusClientMixin.convert_to_registers(number, TO_PYMODBUS[kind], word_order=order)
        assert len(words) == TYPES[kind].registers
        for read_order, read_words in ((order, words), (f"{order}-swap", _swapped(words))):
            raw, value = read_value(TYPES[kind], read_words, read_order)
            expected = ModbusClientMixin.convert_from_registers(words, TO_PYMODBUS[kind], word_order=order)
            if kind.startswith("f"):
                assert isinstance(value, float) and isinstance(expected, float)
                if math.isnan(expected):
                    assert math.isnan(value)
                else:  # as many digits as the type holds
                    digits = 7 if kind == "f32" else 17
                    assert value == float(f"{expected:.{digits}g}")
            else:
                assert value == expected == number
            big = words if order == "big" else words[::-1]
            assert raw == int.from_bytes(struct.pack(f">{len(big)}H", *big), "big")


@given(st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=20))
def test_strings_read_what_pymodbus_writes(text: str) -> None:
    words = ModbusClientMixin.convert_to_registers(text, DATATYPE.STRING)
    assert read_value(TYPES["string"], words, "big") == (None, text.rstrip("\x00"))
    assert read_value(TYPES["string"], _swapped(words), "big-swap") == (None, text)


def test_the_xbt_low_word_first() -> None:
    """The XBT manual's %MF: low word at %MWi, high word at %MWi+1 (XBT:1097-1102)."""
    assert read_value(TYPES["f32"], [0x0000, 0x4048], "little") == (0x40480000, 3.125)
    assert read_value(TYPES["i32"], [0xFFFE, 0xFFFF], "little") == (0xFFFFFFFE, -2)


PROFILE = "[profile]\nid='x'\nname='x'\nsources=['m']\n"
PARAMETER = "[[parameter]]\ncode='{code}'\nname='n'\naddress={address}\nsource='s'\n"


@pytest.mark.parametrize(("extra", "message"), [
    ("type='f16'\n", "parameter A.type: 'f16' is not one of u16, i16"),
    ("type='string'\n", "parameter A: missing 'registers'"),
    ("type='string'\nregisters=0\n", "parameter A.registers: 0 is outside 1..125"),
    ("type='f32'\nregisters=2\n", "parameter A.registers: f32 takes 2; only a string sets its own"),
    ("type='f32'\nword_order='middle'\n", "parameter A.word_order: 'middle' is not one of big, little"),
    ("type='f32'\nenum={ '1' = 'on' }\n", "parameter A.enum: applies to a one-register type, not f32"),
    ("type='u32'\nsigned=true\n", "parameter A.signed: says i16 where type says u32"),
    ("type='u16'\nsigned=true\n", "parameter A.signed: says i16 where type says u16"),
    ("type='string'\nregisters=2\nscale=0.1\n", "parameter A.scale: a string has no scale"),
])
def test_a_bad_value_type_is_named(extra: str, message: str) -> None:
    with pytest.raises(ProfileError, match=message.replace(".", r"\.").replace("(", r"\(")):
        parse_profile(PROFILE + PARAMETER.format(code="A", address=10) + extra, "x.toml")


def test_registers_of_one_parameter_belong_to_no_other() -> None:
    text = PROFILE + PARAMETER.format(code="A", address=10) + "type='f64'\n" + PARAMETER.format(code="B", address=12)
    with pytest.raises(ProfileError, match="parameter B: register 12 is already part of A"):
        parse_profile(text, "x.toml")
    with pytest.raises(ProfileError, match="its 2 registers end past 65535"):
        parse_profile(PROFILE + PARAMETER.format(code="A", address=65535) + "type='u32'\n", "x.toml")


def test_the_profile_s_word_order_is_each_parameter_s_default() -> None:
    text = (PROFILE + "word_order='little'\n" + PARAMETER.format(code="A", address=10) + "type='f32'\n"
            + PARAMETER.format(code="B", address=12) + "type='f32'\nword_order='big'\n")
    profile = parse_profile(text, "x.toml")
    assert [(p.code, p.word_order, p.registers) for p in profile.parameters.values()] == [
        ("A", "little", 2), ("B", "big", 2)]
    assert {address: (p.code, word) for address, (p, word) in profile.words_of.items()} == {
        10: ("A", 0), 11: ("A", 1), 12: ("B", 0), 13: ("B", 1)}


def _capture(path: Path, frames: list[bytes]) -> Path:
    """A text capture of ``frames``, 20 ms apart (exact timing, 19200 8N1)."""
    lines = ["# rtu-capture v1", "# line: 19200 8N1", "# timing: exact"]
    lines += [f"{1.0 + 0.02 * n:.6f} {(frame + crc_bytes(frame)).hex(' ')}" for n, frame in enumerate(frames)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _read(slave: int, address: int, words: list[int]) -> list[bytes]:
    return [struct.pack(">BBHH", slave, 3, address, len(words)),
            struct.pack(f">BBB{len(words)}H", slave, 3, 2 * len(words), *words)]


def test_a_float_that_is_no_number_is_null_in_json_with_its_words(tmp_path: Path,
                                                                   cli: Callable[..., CliResult]) -> None:
    """NaN and infinity are values in the table and in ``values`` CSV, never bare ``NaN`` in
    JSON (``null``, the words kept), and never plotted (``valid`` false, no MCAP member)."""
    nan, inf = struct.unpack(">2H", struct.pack(">f", math.nan)), struct.unpack(">2H", struct.pack(">f", math.inf))
    capture = _capture(tmp_path / "nan.log", _read(247, 2, [*nan, *inf]))
    table = cli("analyze", str(capture), *METER)
    assert "FLOW = nan l/min, F4 = inf" in table.out
    records = cli("analyze", str(capture), *METER, "--format", "jsonl").jsonl()
    answer = next(record for record in records if record.get("role") == "response")
    assert [(p["code"], p["value"], p["words"]) for p in answer["params"]] == [
        ("FLOW", None, list(nan)), ("F4", None, list(inf))]
    values = cli("values", str(capture), *METER, "--format", "jsonl")
    assert [(r["code"], r["value"], r["valid"]) for r in values.jsonl()] == [("FLOW", None, False), ("F4", None, False)]
    assert "NaN" not in values.out and "Infinity" not in values.out
    csv = cli("values", str(capture), *METER).out.splitlines()
    assert [line.split(",")[6:10:3] for line in csv[1:]] == [["FLOW", "nan"], ["F4", "inf"]]


def test_a_request_names_a_parameter_it_reads_whole_once(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    capture = _capture(tmp_path / "read.log", [*_read(247, 2, [0x41B7, 0x7DC0, 1, 2]), *_read(247, 3, [0x4000])])
    records = [r for r in cli("analyze", str(capture), *METER, "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert [[p["address"] for p in r["params"]] for r in records] == [[2, 4], [2, 4], [3], [3]]
    assert [r["summary"] for r in records] == [
        "read HR 2..5 (4): FLOW, F4", "HR = 41B7 7DC0 0001 0002 (4 registers): FLOW = 22.9364 l/min, F4 = 9.18383e-41",
        "read HR 3 (1): FLOW (word 2 of 2)", "HR = 4000 (1 register): FLOW = 16#4000 (word 2 of 2)"]
    assert records[3]["remarks"] == [
        "register 3 is word 2 of 2 of FLOW (f32 at 2-3): one word alone is no value"]
    assert records[3]["params"] == [{"address": 3, "code": "FLOW", "name": "flow", "raw": 0x4000, "value": None,
                                     "unit": None}]


@pytest.fixture
def meter(tmp_path: Path) -> Path:
    if not available():
        pytest.skip("needs ../shared/real beside the checkout")
    return TEXT / "sr_flowmeter_target_20liter_per_min.log"


def test_the_real_flow_meter_s_floats_in_the_table_and_jsonl(meter: Path, cli: Callable[..., CliResult]) -> None:
    """The meter answers IEEE 754 floats, high word first (HR 2-3 = 41B7 7DC0 = 22.9364 l/min
    at a 20 l/min target); its master also reads HR 13 alone, half of a float."""
    records = [r for r in cli("analyze", str(meter), *METER, "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    flow = next(p for p in records[3]["params"] if p["code"] == "FLOW")
    assert flow == {"address": 2, "code": "FLOW", "name": "flow", "raw": 0x41B77DC0, "value": 22.9364,
                    "unit": "l/min", "words": [0x41B7, 0x7DC0]}
    assert [p["code"] for p in records[3]["params"]] == ["F0", "FLOW", "F4", "F6", "F8", "F10", "F12", None]
    half = records[5]
    assert half["params"] == [{"address": 13, "code": "F12", "name": "float at HR 12-13", "raw": 0, "value": None,
                               "unit": None}]
    assert half["remarks"] == ["register 13 is word 2 of 2 of F12 (f32 at 12-13): one word alone is no value"]
    table = cli("analyze", str(meter), *METER).out
    assert "FLOW = 22.9364 l/min, F4 = 0.210566" in table and "F12 = 16#0000 (word 2 of 2) ⚠ register 13" in table


def test_the_real_flow_meter_s_floats_in_values_parquet_mcap_and_rerun(
        meter: Path, tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    """One value per quantity through every output: the float, named once, with its unit; the
    half read of HR 13 a raw word that is no valid value; nothing plotted of it."""
    rows = cli("values", str(meter), *METER, "--format", "jsonl").jsonl()
    flows = [row["value"] for row in rows if row["code"] == "FLOW"]
    assert flows and all(20 < flow < 25 for flow in flows) and flows[0] == 22.9364
    halves = [row for row in rows if row["address"] == 13]
    assert halves and all(row["value"] is None and not row["valid"] for row in halves)
    out = tmp_path
    result = cli("export", str(meter), *METER, "--parquet", str(out / "pq"), "--mcap", str(out / "a.mcap"),
                 "--rrd", str(out / "a.rrd"))
    assert result.code == 0, result.err
    import pyarrow.dataset as ds

    values = ds.dataset(out / "pq" / "values").to_table().to_pylist()
    flow_rows = [row for row in values if row["code"] == "FLOW"]
    assert [row["value"] for row in flow_rows] == flows
    assert flow_rows[0]["raw"] == 0x41B7 and flow_rows[0]["unit"] == "l/min"
    assert all(row["value"] is None and not row["valid"] for row in values if row["address"] == 13)
    from mcap.reader import make_reader

    with (out / "a.mcap").open("rb") as stream:
        params = [json.loads(message.data) for _, channel, message in make_reader(stream).iter_messages()
                  if channel.topic == "/slave/247/params"]
    assert [p["FLOW"] for p in params if "FLOW" in p] == flows
    assert not any("F12" in p and len(p) == 2 for p in params)  # the half read alone: no member
    from tests.test_exports import _rerun_rows

    _, plotted, _ = _rerun_rows(out / "a.rrd")
    (path,) = [path for path in plotted if path.endswith("/FLOW")]
    assert plotted[path] == pytest.approx(flows)
    assert not any(path.endswith("/F12") and len(series) != len(flows) for path, series in plotted.items())


@given(st.lists(st.one_of(st.floats(width=32), st.floats()), min_size=1, max_size=50))
def test_floats_are_rounded_as_python_formats_them(numbers: list[float]) -> None:
    """The 7 significant digits of an f32 (or a scaled value), many at once, are exactly what
    ``float(f"{number:.7g}")`` makes of each; NaN and infinities stay."""
    rounded = significant(np.array(numbers, np.float64), 7).tolist()
    for number, made in zip(numbers, rounded, strict=True):
        if math.isnan(number):
            assert math.isnan(made)
        else:
            assert made == float(f"{number:.7g}")


@pytest.mark.parametrize("kind", ["u32", "i32", "f32", "f64", "string"])
@given(words=st.lists(st.integers(0, 0xFFFF), min_size=4, max_size=4), scale=st.sampled_from([1.0, 0.1]),
       unit=st.sampled_from([None, "", "l/min"]), asked=st.booleans())
def test_values_named_at_once_are_what_show_says_of_each(kind: str, words: list[int], scale: float,
                                                         unit: str | None, asked: bool) -> None:
    """A namer names a batch of values at once (params built by ``map``, texts formatted at
    once); each is the param of that value alone and the text :func:`show` makes of it, NaN and
    infinities, scales, units and requests' values (no words) included."""
    size = TYPES[kind].registers or 2
    parameter = Parameter(40, "F", "flow", "test", type=kind, registers=size, word_order="little",
                          scale=1.0 if kind == "string" else scale, unit=unit)
    profile = Profile("test", "test", "slave", ("test",), {40: parameter})
    values: list[tuple[int | None, ...]] = [tuple(words[:size]), tuple(reversed(words[:size]))]
    if asked:
        values.append((None,) * size)

    def namer() -> AddressNamer:
        return AddressNamer(profile, 40, ("F", "flow"), parameter, reported=True, learns=False)

    for (param, text), each in zip(namer().make_values(values), values, strict=True):
        ((alone, _),) = namer().make_values([each])
        assert repr(param) == repr(alone) and text == show(param)


def test_the_xbt_sample_s_floats_and_double_word_low_word_first(cli: Callable[..., CliResult]) -> None:
    """captures/xbt-floats: the XBT's %MF30/%MF32 floats and %MD34 double word, low word first
    (XBT:1097-1102), named by the sample project's profile; a read of %MW31 alone remarked on;
    the written setpoint %MF36 a value."""
    captures = Path(__file__).resolve().parents[1] / "captures"
    project = ("--profile-file", str(captures / "xbt-project.toml"), "--profile", "54=xbt-project")
    rows = cli("values", str(captures / "xbt-floats.log"), *project, "--format", "jsonl").jsonl()
    levels = [row["value"] for row in rows if row["code"] == "%MF30" and row["valid"]]
    assert len(levels) == 6 and all(62 < level < 63.5 for level in levels)
    assert [row["value"] for row in rows if row["code"] == "%MD34"] == [1407, 1407, 1407, 1408, 1408, 1408]
    assert [(row["kind"], row["value"], row["unit"]) for row in rows if row["code"] == "%MF36"] == [
        ("written", 70.0, "%")]
    half = [row for row in rows if row["address"] == 31]
    assert [(row["code"], row["value"], row["valid"]) for row in half] == [("%MF30", None, False)]
    table = cli("analyze", str(captures / "xbt-floats.log"), *project).out
    assert "%MF30 = 62.58646 %, %MF32 = 12.04665 m3/h, %MD34 = 1407" in table
    assert "register 31 is word 2 of 2 of %MF30 (f32 at 30-31)" in table
