"""``profiles import MAP.csv``: register maps as vendors and spreadsheets write them become
checked profiles; a bad row is one line naming its row and column."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import CliResult
from tests.real_recordings import TEXT, available

#: A meter's map as a spreadsheet saves it (semicolons, decimal commas, Modicon references,
#: types and word orders in the words vendors use, a section title, a coil and an input).
METER_MAP = """\ufeffModbus Register;Tag;Description;Units;Data Type;Word Order;Scale;R/W;Length
Measurements;;;;;;;;
40001;;Status;;UINT16;;;R;
40003;FLOW;Flow rate;l/min;FLOAT;ABCD;;R;
40005;;Total volume;m3;Float32;high word first;;R;
40007;TEMP;Temperature;°C;INT16;;0,1;R;
40011;CNT;Pulse counter;;UDINT;CDAB;;RW;
40013;SN;Serial number;;ASCII;;;R;4
00001;RUN;Pump run;;BOOL;;;RW;
10002;ALM;Alarm;;;;;R;
"""


def _import(tmp_path: Path, cli: Callable[..., CliResult], text: str, *options: str,
            name: str = "meter.csv") -> CliResult:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return cli("profiles", "import", str(path), *options)


def test_a_spreadsheet_s_map_becomes_a_checked_profile(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    out = tmp_path / "meter.toml"
    result = _import(tmp_path, cli, METER_MAP, "-o", str(out))
    assert result.code == 0, result.err
    said = result.err.splitlines()
    assert said[0] == f"{tmp_path / 'meter.csv'}: addresses read as Modicon references (coils, discrete inputs, " \
                      "registers)"
    assert said[1] == f"{tmp_path / 'meter.csv'}: skipped 1 rows of one cell (titles?): 2"
    assert said[2].startswith(f"wrote {out}: profile 'meter'")
    profile = tomllib.loads(out.read_text())
    assert profile["profile"] == {"id": "meter", "name": "meter", "sources": ["register map meter.csv"]}
    parameters = {p["address"]: p for p in profile["parameter"]}
    assert parameters[0] == {"address": 0, "code": "STATUS", "name": "Status", "access": "r",
                             "source": "meter.csv row 3"}
    assert parameters[2] == {"address": 2, "code": "FLOW", "name": "Flow rate", "unit": "l/min", "type": "f32",
                             "word_order": "big", "access": "r", "source": "meter.csv row 4"}
    assert parameters[4]["code"] == "TOTAL_VOLUME" and parameters[4]["word_order"] == "big"
    assert (parameters[6]["type"], parameters[6]["scale"], parameters[6]["unit"]) == ("i16", 0.1, "°C")
    counter = parameters[10]  # read-write: the default access, not written
    assert (counter["type"], counter["word_order"], "access" in counter) == ("u32", "little", False)
    assert (parameters[12]["type"], parameters[12]["registers"]) == ("string", 4)
    assert profile["coil"] == [{"address": 0, "code": "RUN", "name": "Pump run", "source": "meter.csv row 9"}]
    assert profile["input"] == [{"address": 1, "code": "ALM", "name": "Alarm", "source": "meter.csv row 10"}]
    assert cli("profiles", "check", str(out)).code == 0


def test_wire_and_one_based_addresses_and_hex(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    text = "address,name,type\n0x0C81,Status word,\n3204,Current,int16\n"
    wire = _import(tmp_path, cli, text)
    assert "addresses read as sent on the wire, from 0 (--addressing 1 if the map counts from 1)" in wire.err
    assert [p["address"] for p in tomllib.loads(wire.out)["parameter"]] == [3201, 3204]
    counted = _import(tmp_path, cli, text, "--addressing", "1", "--id", "atv", "--name", "Drive")
    profile = tomllib.loads(counted.out)
    assert [p["address"] for p in profile["parameter"]] == [3200, 3203]
    assert (profile["profile"]["id"], profile["profile"]["name"]) == ("atv", "Drive")
    refs = _import(tmp_path, cli, text, "--addressing", "4x")
    assert refs.code == 12 and "--addressing 4x: not every address is a Modicon reference" in refs.err


def test_every_bad_row_is_one_line_and_nothing_is_written(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    text = ("Address,Name,Type,Word order,Scale,Length\n"
            "10,Flow,float,CDBA,,\n"     # row 2: an order no map means
            "twelve,Level,,,,\n"         # row 3: no address
            "14,Text,string,,,\n"        # row 4: a string without its length
            "20,Speed,uint16,,ten,\n"    # row 5: no factor
            "30,,u16,,,\n"               # row 6: no name
            "40,Volume,f32,,,\n"
            "41,Clash,u16,,,\n")         # row 8: inside the float at 40
    out = tmp_path / "bad.toml"
    result = _import(tmp_path, cli, text, "-o", str(out), name="bad.csv")
    path = tmp_path / "bad.csv"
    assert result.code == 12
    assert result.err.splitlines() == [
        f"error: {path}: row 2, column D (word_order): 'CDBA' is not a word order (ABCD, CDAB, …)",
        f"{path}: row 3, column A (address): 'twelve' is no address (a number, or 0x0C81)",
        f"{path}: row 4, column F (registers): a string needs its registers, 1 to 125",
        f"{path}: row 5, column E (scale): 'ten' is no factor (0.1, 1/10, 0,1)",
        f"{path}: row 6, column B (name): is empty",
        f"{path}: row 8, column A (address): register 41 is already row 7's",
        "nothing written"]
    assert not out.exists()


@pytest.mark.parametrize(("text", "said"), [
    ("Register,Value\n1,2\n", "row 1 (the header): no column of name (headers: 'Register', 'Value'); name them, "
     "e.g. 'Address' and 'Name'"),
    ("Address,Name\n", "has no rows under its header"),
    ("\x00\x01PK", "holds NUL bytes: not a CSV text (an .xlsx? save it as CSV)"),
])
def test_a_map_that_is_no_map(tmp_path: Path, cli: Callable[..., CliResult], text: str, said: str) -> None:
    result = _import(tmp_path, cli, text)
    assert result.code == 12 and result.err == f"error: {tmp_path / 'meter.csv'}: {said}\n"
    missing = cli("profiles", "import", str(tmp_path / "none.csv"))
    assert missing.code == 3 and missing.err == f"error: {tmp_path / 'none.csv'}: no such register map\n"


def test_an_imported_map_names_the_real_flow_meter_s_floats(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    if not available():
        pytest.skip("needs ../shared/real beside the checkout")
    out = tmp_path / "flowmeter.toml"
    made = _import(tmp_path, cli, "Register,Name,Unit,Type\n3,Flow,l/min,REAL\n5,F4,,REAL\n", "--addressing", "1",
                   "-o", str(out), name="flowmeter.csv")
    assert made.code == 0, made.err
    records = cli("analyze", str(TEXT / "sr_flowmeter_target_20liter_per_min.log"), "--profile-file", str(out),
                  "--profile", "flowmeter", "--format", "jsonl").jsonl()
    assert [(p["code"], p["value"]) for p in records[4]["params"] if p["code"]] == [("FLOW", 22.9364),
                                                                                    ("F4", 0.210566)]


def test_a_map_past_a_profile_s_size_is_one_line(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    rows = ["Address,Name,Type", *(f"{address},A long descriptive name of register {address},float"
                                   for address in range(0, 40_000, 2))]
    result = _import(tmp_path, cli, "\n".join(rows), "-o", str(tmp_path / "big.toml"), "-q")
    assert result.code == 12 and result.err.startswith(f"error: {tmp_path / 'meter.csv'}: its profile would be ")
    assert result.err.endswith(" characters, past the 1,048,576 a profile may hold: split it\n")
    assert not (tmp_path / "big.toml").exists()
