"""Narrowed to what matters: windows, limits and filters on every command that reads a capture,
damaged frames explained, register values as manuals write them."""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from contextlib import redirect_stderr
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from decoders.damage import byte_diff, crc_note
from decoders.message import ParamValue
from decoders.modbus.pdu import ReadRequest, RegistersResponse, WriteSingle
from decoders.register_format import RegisterFormat
from sniffer.cli import main
from tests.conftest import SAMPLE_LOG, SAMPLE_MCAP, CliResult

Cli = Callable[..., CliResult]


def frames(result: CliResult) -> list[dict[str, object]]:
    assert result.code == 0, result.err
    return [record for record in result.jsonl() if record["kind"] == "frame"]


def shown_indexes(result: CliResult) -> list[int]:
    assert result.code == 0, result.err
    return [int(line.split()[0]) for line in result.out.splitlines() if not line.startswith("#")]


def test_time_window_offsets_and_clock_times(cli: Cli) -> None:
    everything = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl"))
    start = float(str(everything[0]["t"]))
    # Frames from 1 s to 2 s after the first frame's start.
    window = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--from", "1s", "--to", "2000ms"))
    expected = [f["index"] for f in everything if 1 <= float(str(f["t"])) - start <= 2]
    assert [f["index"] for f in window] == expected and 10 < len(expected) < 40
    # The same window as times of day (UTC) and as dates.
    by_clock = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--from", "22:13:21", "--to", "22:13:22"))
    assert [f["index"] for f in by_clock] == expected
    by_date = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--from", "2023-11-14 22:13:21",
                         "--to", "2023-11-14T22:13:22Z"))
    assert [f["index"] for f in by_date] == expected
    # The summary counts the window only.
    summary = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--from", "1s", "--to", "2s").jsonl()[-1]
    assert summary["frames"] == len(expected)


def test_a_window_that_misses_the_capture_says_where_the_frames_are(cli: Cli) -> None:
    """A time of day in the wrong zone or an index past the end selects nothing: one warning
    says where the capture's frames lie, and the (empty) output is still written, exit 0."""
    later = cli("analyze", str(SAMPLE_LOG), "--from", "23:00")
    assert later.code == 0 and "# 0 frames" in later.out
    assert later.err.strip() == (f"warning: {SAMPLE_LOG}: no frame falls in the window of --from/--to/--around: the "
                                 "capture's 52 frames run from 2023-11-14 22:13:20.000 to 2023-11-14 22:13:22.659 UTC "
                                 "(#0 to #51)")
    earlier = cli("stats", str(SAMPLE_LOG), "--to", "21:00", "--jobs", "2")
    assert earlier.code == 0 and earlier.err.count("warning:") == 1
    assert "first frame starts at 2023-11-14 22:13:20.000 UTC, after the window's end" in earlier.err
    assert "no frame falls" in cli("analyze", str(SAMPLE_LOG), "--around", "900").err
    assert cli("analyze", str(SAMPLE_LOG), "--from", "22:13:21").err == ""


def test_answers_in_a_window_keep_their_request(cli: Cli) -> None:
    """A window that starts between a request and its answer: the answer is still paired and
    decoded with the request's addresses."""
    window = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--around", "7", "--context", "0",
                        "--profile", "atv71"))
    assert [f["index"] for f in window] == [7]
    assert window[0]["request_index"] == 6 and "SFr = 4.0 kHz" in str(window[0]["summary"])


def test_around_limit_and_stats(cli: Cli) -> None:
    assert shown_indexes(cli("analyze", str(SAMPLE_LOG), "--around", "25", "--context", "2")) == [23, 24, 25, 26, 27]
    assert shown_indexes(cli("analyze", str(SAMPLE_LOG), "--around", "3")) == list(range(0, 14))
    assert shown_indexes(cli("analyze", str(SAMPLE_MCAP), "--limit", "3")) == [0, 1, 2]
    limited = cli("analyze", str(SAMPLE_LOG), "--limit", "2", "--filter", "role=exception")
    assert shown_indexes(limited) == [31, 41]
    assert "# 2 of 42 frames shown" in limited.out  # read up to the second exception
    stats = json.loads(cli("stats", str(SAMPLE_LOG), "--format", "json", "--around", "25", "--context", "2").out)
    assert stats["frames"] == 5 and stats["crc_errors"] == 1


def test_windowed_export_holds_the_window_only(cli: Cli, tmp_path: Path) -> None:
    """The MCAP export of a window is a capture of that window: analysing it gives the same frames,
    at the same times (raw chunks cut with the frames)."""
    out = tmp_path / "window.mcap"
    assert cli("export", str(SAMPLE_LOG), "--mcap", str(out), "--from", "1s", "--to", "2s", "--jobs", "2").code == 0
    original = frames(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--from", "1s", "--to", "2s"))
    again = frames(cli("analyze", str(out), "--format", "jsonl"))
    assert [(f["t_ns"], f["hex"]) for f in again] == [(f["t_ns"], f["hex"]) for f in original]
    pcap = tmp_path / "three.pcap"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(pcap), "--limit", "3").code == 0
    assert pcap.stat().st_size == 24 + sum(16 + 28 + n for n in (7, 55, 8))  # each in IPv4 (20) and UDP (8)


@pytest.mark.parametrize(("options", "error"), [
    (["--from", "yesterday"], "--from yesterday: give an offset"),
    (["--to", "25:00"], "--to 25:00: give an offset"),
    (["--from", "5s", "--to", "1s"], "--to 1s is before --from 5s"),
    (["--context", "3"], "--context goes with --around"),
])
def test_bad_windows_are_one_line(cli: Cli, options: list[str], error: str) -> None:
    result = cli("analyze", str(SAMPLE_LOG), *options)
    assert result.code == 2 and error in result.err and len(result.err.strip().splitlines()) == 1


def test_empty_window_says_so(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--from", "1h")
    assert result.code == 0 and "# 0 frames" in result.out


@pytest.mark.parametrize(("spec", "expected"), [
    (["crc=bad"], [25]),
    (["exception=2"], [31]),
    (["exception=0x04"], [41]),
    (["address=3201"], [40, 41]),
    (["address=8400-8401", "role=exception"], [31]),
    (["param=hsp", "role=response"], [7, 14, 25, 27, 34, 45]),
    (["latency>5.5", "slave=2"], [7, 25]),
    (["latency<=2.1"], [3, 47]),
])
def test_filters(cli: Cli, spec: list[str], expected: list[int]) -> None:
    options = [a for s in spec for a in ("--filter", s)]
    result = cli("analyze", str(SAMPLE_LOG), "--profile", "atv71", *options)
    assert shown_indexes(result) == expected
    assert f"# {len(expected)} of 52 frames shown" in result.out


@pytest.mark.parametrize(("spec", "error"), [
    ("crc=maybe", "crc is one of ok, bad"),
    ("address=9-3", "the range ends before it starts"),
    ("latency>soon", "give milliseconds"),
    ("colour=red", "use KEY=VALUE with KEY one of"),
])
def test_bad_filters_are_one_line(cli: Cli, spec: str, error: str) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--filter", spec)
    assert result.code == 2 and error in result.err


def test_damaged_answer_shows_crc_and_its_difference_from_the_good_retry(cli: Cli) -> None:
    out = cli("analyze", str(SAMPLE_LOG), "--around", "26", "--context", "1").out
    damaged = next(line for line in out.splitlines() if line.split()[0] == "25")
    assert "CRC 52 b0 on the wire, b3 71 computed" in damaged
    good = next(line for line in out.splitlines() if line.split()[0] == "27")
    assert "good retry of damaged #25: byte 6 50, good 58 (one bit, 0x08)" in good


def test_crc_note() -> None:
    assert crc_note(bytes.fromhex("02030c1e0004276c")) is None
    assert crc_note(bytes.fromhex("02030c1e0004276d")) == "CRC 27 6d on the wire, 27 6c computed"
    assert crc_note(b"\x02\x03") is None


@given(st.binary(min_size=1, max_size=40), st.data())
def test_byte_diff_names_exactly_the_differing_bytes(good: bytes, data: st.DataObject) -> None:
    flips = data.draw(st.lists(st.integers(0, len(good) - 1), min_size=1, max_size=3, unique=True))
    damaged = bytearray(good)
    for place in flips:
        damaged[place] ^= data.draw(st.integers(1, 255))
    text = byte_diff(bytes(damaged), good)
    for place in sorted(flips):
        assert f"byte {place} {damaged[place]:02x}, good {good[place]:02x}" in text
    assert text.count("byte ") == len(flips)


def test_register_formats() -> None:
    """The table's register texts: words in hex, or the values the decoding typed (a register
    left over from a value the frame does not carry whole after ``+``); addresses as sent, from
    1, or as Modicon references."""
    words = [ParamValue(0, raw=0x4048, value=0x4048), ParamValue(1, raw=0xF5C3, value=-2621)]
    assert RegisterFormat().values(words) == "0x4048 0xF5C3"
    assert RegisterFormat(typed=True).values(words) == "16456 -2621"
    pair = ParamValue(100, raw=0x4048F5C3, value=3.14, words=(0x4048, 0xF5C3))
    half = ParamValue(102, raw=0xFFFF, value=None, available=False)
    assert RegisterFormat(typed=True).values([pair, half]) == "3.14 +65535"
    one, modicon = RegisterFormat(addressing="1"), RegisterFormat(addressing="4x")
    assert one.summary(ReadRequest(3, 0, 2), []) == "read HR 1..2 (2)"
    assert modicon.summary(ReadRequest(4, 9, 1), []) == "read IR 30010 (1)"
    assert modicon.summary(ReadRequest(1, 0, 8), []) == "read coils 00001..00008 (8)"
    assert modicon.summary(ReadRequest(3, 65535, 1), []) == "read HR 465536 (1)"
    answer = RegistersResponse(3, 4, (0x4048, 0xF5C3))
    assert RegisterFormat(typed=True).summary(answer, [pair]) == "HR 100..101 = 3.14"
    assert RegisterFormat().summary(answer, []) == "HR = 0x4048 0xF5C3"
    assert RegisterFormat(typed=True).summary(WriteSingle(6, 7, 0xFFFF), [ParamValue(7, raw=0xFFFF, value=-1)]) == (
        "write HR 7 = -1")
    with pytest.raises(ValueError, match="addressing"):
        RegisterFormat(addressing="5x")


def test_registers_typed_on_the_command_line(cli: Cli) -> None:
    """``--registers`` types the registers of slaves without a profile for every output: pairs
    as floats in the table, ``values`` and JSONL; a range leaves the others words; a range that
    is no whole number of its type, two that overlap, a bad type or order: one line, exit 2."""
    out = cli("analyze", str(SAMPLE_LOG), "--registers", "s16", "--filter", "slave=12", "--format", "jsonl").jsonl()
    assert [p["value"] for p in out[2]["params"]] == [-32768, 3, 2]
    result = cli("analyze", str(SAMPLE_LOG), "--registers", "3000-3002=f32")
    assert result.code == 2 and result.err == (
        "error: --registers 3000-3002=f32: 3 registers are no whole number of f32 (2 registers each)\n")
    for bad, said in (("f31", "'f31' is not one of hex, u16"), ("f32:middle", "word order 'middle' is not one of"),
                      ("9-3=u16", "'9-3': give addresses 0 to 65535"), ("a-b=u16", "'a-b' is no register range")):
        err = io.StringIO()
        with pytest.raises(SystemExit) as refused, redirect_stderr(err):
            main(["analyze", str(SAMPLE_LOG), "--registers", bad])
        assert refused.value.code == 2 and said in err.getvalue() and len(err.getvalue().splitlines()) == 1
    both = cli("analyze", str(SAMPLE_LOG), "--registers", "0-9=f32", "--registers", "8=u16")
    assert both.code == 2 and "--registers 0-9=f32 and 8=u16 both type register 8" in both.err


def test_registers_on_the_command_line(cli: Cli) -> None:
    out = cli("analyze", str(SAMPLE_LOG), "--registers", "u16", "--addressing", "4x", "--filter", "slave=12").out
    assert "read HR 48401..48403 (3)" in out and "HR 48401..48403 = 32768 3 2" in out
    profiled = cli("analyze", str(SAMPLE_LOG), "--registers", "u16", "--profile", "atv71", "--around", "7",
                   "--context", "0").out
    assert "SFr = 4.0 kHz" in profiled  # a profile's names and units win over raw registers


def test_quiet_and_what_was_written(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "table.txt"
    told = cli("analyze", str(SAMPLE_LOG), "-o", str(out), "--filter", "role=exception")
    assert told.code == 0 and told.err.startswith(f"wrote {out}: table, 2 frames, ")
    assert cli("analyze", str(SAMPLE_LOG), "-o", str(out), "--force", "-q").err == ""
    stats = tmp_path / "stats.json"
    assert "json statistics of 52 frames" in cli("stats", str(SAMPLE_LOG), "--format", "json", "-o", str(stats)).err
