"""``profiles draft``: a profile drafted from a capture recovers the types of known maps, reads
the real flow meter's floats, and is a profile rtusniff loads."""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from benchmarks.device_maps import recovered, write_devices
from tests.conftest import CliResult
from tests.real_recordings import TEXT, available


def test_draft_recovers_nine_types_in_ten_of_known_maps(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    """Eight devices of random maps (floats in both word orders, counters, enumerations, signed
    words, texts), polled 60 times: the drafts type 90 % of their values or more."""
    capture = tmp_path / "devices.mcap"
    maps = write_devices(capture, 8, 60, seed=1)
    drafts = {}
    for slave in maps:
        out = tmp_path / f"slave{slave}.toml"
        result = cli("profiles", "draft", str(capture), "--slave", str(slave), "-o", str(out))
        assert result.code == 0, result.err
        assert result.err.startswith(f"wrote {out}: draft profile 'slave{slave}'")
        drafts[slave] = out.read_text()
    right, total, missed = recovered(maps, drafts)
    assert right >= 0.9 * total, missed


def test_a_draft_is_a_profile_with_its_evidence(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    capture = tmp_path / "devices.mcap"
    maps = write_devices(capture, 2, 20, seed=3)
    out = tmp_path / "draft.toml"
    assert cli("profiles", "draft", str(capture), "--slave", "1", "-o", str(out), "--id", "meter").code == 0
    assert cli("profiles", "check", str(out)).code == 0
    text = out.read_text()
    assert text.startswith("# Drafted by 'rtusniff profiles draft' from devices.mcap, slave 1")
    draft = tomllib.loads(text)
    assert draft["profile"]["id"] == "meter" and len(draft["parameter"]) >= len(maps[1]) - 2
    # Every entry says what was seen: how often read, the words' range.
    assert text.count("# read ") == len(draft["parameter"])
    # Used as it is, it names the capture's values.
    table = cli("analyze", str(capture), "--profile-file", str(out), "--profile", "1=meter", "--filter", "slave=1")
    assert table.code == 0 and "R0" in table.out
    again = cli("profiles", "draft", str(capture), "--slave", "1", "-o", str(out))
    assert again.code == 11 and "exists; add --force" in again.err


def test_draft_reads_the_real_flow_meter_s_floats(cli: Callable[..., CliResult]) -> None:
    """The flow meter of sigrok's recordings: floats, high word first, at HR 2-3 (the flow),
    4-5 and 8-9; a draft says so, and why."""
    if not available():
        pytest.skip("needs ../shared/real beside the checkout")
    result = cli("profiles", "draft", str(TEXT / "sr_flowmeter_target_20liter_per_min.log"), "--slave", "247")
    assert result.code == 0, result.err
    typed = {entry["address"]: (entry.get("type", "u16"), entry.get("word_order"))
             for entry in tomllib.loads(result.out)["parameter"]}
    assert typed[2] == typed[4] == typed[8] == ("f32", "big")
    assert "# as f32 big every reading is a measurement, 22.9364 to 22.93879, moving steadily" in result.out


def test_draft_says_what_it_cannot_do(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    capture = tmp_path / "devices.mcap"
    write_devices(capture, 1, 3, seed=1)
    nobody = cli("profiles", "draft", str(capture), "--slave", "9")
    assert nobody.code == 14 and nobody.err == (
        f"error: {capture}: slave 9 reports and is written no value in this capture\n")
    wrong = cli("profiles", "draft", str(capture), "--slave", "300")
    assert wrong.code == 2 and wrong.err == "error: --slave: give a slave address, 1 to 247\n"


def test_a_draft_past_a_profile_s_size_is_one_line(tmp_path: Path, cli: Callable[..., CliResult]) -> None:
    """A slave read at 12 000 registers: their draft would pass the 1 MiB a profile may hold
    even without the evidence; one line and exit 12, nothing written. (``--debug`` is taken
    after an action too.)"""
    import random
    import struct

    from benchmarks.bench_framing import exchange
    from benchmarks.bench_memory import write_capture

    rng = random.Random(1)
    traffic = [transmission for first in range(0, 12_000, 120) for transmission in exchange(
        rng, struct.pack(">BBHH", 1, 3, first, 120), struct.pack(">BBB120H", 1, 3, 240, *range(first, first + 120)))]
    capture = tmp_path / "wide.mcap"
    write_capture(capture, len(traffic), lambda frames, piece: traffic[piece : piece + frames])
    out = tmp_path / "draft.toml"
    result = cli("profiles", "draft", str(capture), "--slave", "1", "-o", str(out))
    assert result.code == 12 and result.err.startswith(f"error: {capture}: slave 1 has 12,000 registers, coils and "
                                                       "inputs: a profile of them (")
    assert result.err.endswith("draft a capture of fewer of them\n") and not out.exists()
    assert cli("profiles", "show", "atv71", "--debug").code == 0
