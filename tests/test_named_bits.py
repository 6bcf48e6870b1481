"""Coils and discrete inputs by name: a profile's ``[[coil]]`` and ``[[input]]`` through the
table, JSONL, ``values``, Parquet and MCAP, in columns and one by one alike."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.reader import make_reader

from decoders.crc import crc_bytes
from decoders.profiles.parse import ProfileError, parse_profile
from tests.conftest import CliResult

PUMP = Path(__file__).parent / "data" / "pump.toml"
NAMED = ("--profile-file", str(PUMP), "--profile", "pump")
#: Read coils 0-7 (RUN and REV on), inputs 0-1 (ALM on), write coil 3 on and its echo, write
#: coils 99-101 (RST on) and the answer.
FRAMES = [bytes([1, 1, 0, 0, 0, 8]), bytes([1, 1, 1, 0b1001]), bytes([1, 2, 0, 0, 0, 2]), bytes([1, 2, 1, 1]),
          bytes([1, 5, 0, 3, 0xFF, 0]), bytes([1, 5, 0, 3, 0xFF, 0]), bytes([1, 15, 0, 99, 0, 3, 1, 0b010]),
          bytes([1, 15, 0, 99, 0, 3])]


@pytest.fixture
def capture(tmp_path: Path) -> Path:
    path = tmp_path / "pump.log"
    lines = ["# rtu-capture v1", "# line: 19200 8N1", "# timing: exact"]
    lines += [f"{1.0 + 0.02 * n:.6f} {(frame + crc_bytes(frame)).hex(' ')}" for n, frame in enumerate(FRAMES)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_coils_and_inputs_are_named_in_the_table_and_jsonl(capture: Path, cli: Callable[..., CliResult]) -> None:
    records = [r for r in cli("analyze", str(capture), *NAMED, "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert [r["summary"] for r in records] == [
        "read coils 0..7 (8): RUN, REV", "coils = 10010000 (1 bytes): RUN = ON, REV = ON",
        "read inputs 0..1 (2): ALM", "inputs = 10000000 (1 bytes): ALM = ON",
        "write coil 3 = ON: REV = ON", "write coil 3 = ON: REV = ON",
        "write coils 99..101 = 010: RST = ON", "wrote coils 99..101 (3): RST"]
    named = [(p["address"], p["code"], p["value"]) for p in records[1]["params"] if p["code"]]
    assert named == [(0, "RUN", True), (3, "REV", True)]
    # Coil 1, which the profile does not name, is its address and bit as before.
    assert records[1]["params"][1] == {"address": 1, "code": None, "name": None, "raw": 0, "value": 0, "unit": None}
    assert [(p["code"], p["value"]) for p in records[3]["params"]] == [("ALM", True), (None, 0)]


def test_coils_by_name_in_values_parquet_and_mcap(capture: Path, tmp_path: Path,
                                                  cli: Callable[..., CliResult]) -> None:
    rows = cli("values", str(capture), *NAMED, "--param", "RUN", "--param", "REV", "--format", "jsonl").jsonl()
    assert [(r["kind"], r["code"], r["value"]) for r in rows] == [
        ("reported", "RUN", True), ("reported", "REV", True), ("written", "REV", True), ("reported", "REV", True)]
    csv = cli("values", str(capture), *NAMED, "--param", "ALM").out.splitlines()
    assert csv[1].split(",")[6:10] == ["ALM", "Alarm", "1", "true"]
    result = cli("export", str(capture), *NAMED, "--parquet", str(tmp_path / "pq"), "--mcap", str(tmp_path / "a.mcap"))
    assert result.code == 0, result.err
    import pyarrow.dataset as ds

    values = ds.dataset(tmp_path / "pq" / "values").to_table().to_pylist()
    assert [(r["code"], r["value"]) for r in values if r["code"]] == [
        ("RUN", 1.0), ("REV", 1.0), ("ALM", 1.0), ("REV", 1.0), ("REV", 1.0), ("RST", 1.0)]
    with (tmp_path / "a.mcap").open("rb") as stream:
        params = [json.loads(m.data) for _, channel, m in make_reader(stream).iter_messages()
                  if channel.topic == "/slave/1/params"]
    assert params[0]["RUN"] is True and params[0]["REV"] is True and params[0]["1"] == 0


def test_a_profile_names_a_coil_or_input_once_and_only_as_on_or_off() -> None:
    head = "[profile]\nid='x'\nname='x'\nsources=['m']\n"
    coil = "[[coil]]\naddress=1\ncode='{code}'\nname='n'\nsource='s'\n"
    with pytest.raises(ProfileError, match="coil B: address 1 is already A"):
        parse_profile(head + coil.format(code="A") + coil.format(code="B"), "x.toml")
    with pytest.raises(ProfileError, match="coil or input A: code appears twice"):
        parse_profile(head + coil.format(code="A") + coil.format(code="A").replace("address=1", "address=2"), "x.toml")
    with pytest.raises(ProfileError, match=re.escape("coil A.scale: a coil has no 'scale' (it is on or off)")):
        parse_profile(head + coil.format(code="A") + "scale=2\n", "x.toml")
    both = parse_profile(head + coil.format(code="A") + coil.format(code="B").replace("[[coil]]", "[[input]]"),
                         "x.toml")
    assert (list(both.coils), list(both.inputs)) == ([1], [1])
