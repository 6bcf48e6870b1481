"""``rtusniff analyze`` and ``convert`` as a user runs them."""

from __future__ import annotations

import gc
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from sniffer import cli as rtusniff_cli
from tests.conftest import CAPTURES, SAMPLE_LOG, SAMPLE_MCAP, CliResult

Cli = Callable[..., CliResult]
FRAME_FIELDS = {
    "kind": str, "index": int, "t": float, "t_end": float, "hex": str, "crc_ok": bool, "slave": (int, type(None)),
    "function": (int, type(None)), "role": str, "exception_code": (int, type(None)), "flags": list,
    "request_index": (int, type(None)), "latency_s": (float, type(None)), "params": list, "summary": str,
}


def test_analyze_table_shows_every_frame(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--hex")
    assert result.code == 0, result.err
    assert "line 19200 8E1  timing exact" in result.out
    assert "0203080028025001f4000052b0" in result.out  # the damaged response
    assert "gap_1_5" in result.out
    assert result.out.rstrip().endswith(
        "# 52 frames, 28 request, 21 response, 2 exception, 1 noise, 1 CRC error, 1 gap_1_5, 5 retry, "
        "1 short_idle, 4 timeout"
    )


def test_analyze_jsonl_follows_the_contract(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl")
    assert result.code == 0, result.err
    records = result.jsonl()
    assert records[0]["kind"] == "capture" and records[0]["timing"] == "exact"
    assert records[-1]["kind"] == "summary" and records[-1]["frames"] == 52
    frames = [r for r in records if r["kind"] == "frame"]
    assert [f["index"] for f in frames] == list(range(len(frames)))
    for frame in frames:
        for name, kind in FRAME_FIELDS.items():
            assert isinstance(frame[name], kind), (name, frame)
        assert frame["hex"] == frame["hex"].lower()
        assert frame["t"] <= frame["t_end"]
    capture_bytes = bytes.fromhex("".join(line.split(" ", 1)[1] for line in SAMPLE_LOG.read_text().splitlines()
                                          if not line.startswith("#")))
    assert bytes.fromhex("".join(f["hex"] for f in frames)) == capture_bytes
    bad = [f for f in frames if not f["crc_ok"] and f["role"] != "noise"]
    assert [f["hex"] for f in bad] == ["0203080028025001f4000052b0"]
    exceptions = [(f["slave"], f["function"], f["exception_code"]) for f in frames if f["role"] == "exception"]
    assert exceptions == [(12, 3, 2), (4, 16, 4)]
    flagged = {f["index"]: f["flags"] for f in frames if f["flags"]}
    assert flagged == {
        12: ["timeout"], 19: ["timeout", "retry"], 26: ["retry"], 32: ["timeout", "retry"], 36: ["gap_1_5"],
        39: ["timeout", "retry"], 47: ["short_idle"], 51: ["retry"],
    }
    [noise] = [f for f in frames if f["role"] == "noise"]
    assert (noise["hex"], noise["crc_ok"], noise["slave"], noise["function"]) == ("00", False, None, None)
    for frame in frames:
        if frame["role"] in ("response", "exception"):
            request = frames[frame["request_index"]]
            asked = (request["role"], request["slave"], request["function"])
            assert asked == ("request", frame["slave"], frame["function"])
            assert frame["latency_s"] == pytest.approx(frame["t"] - request["t_end"], abs=1e-6)
        else:
            assert frame["request_index"] is None and frame["latency_s"] is None
    # Slave 2 identified itself as an ATV71 (frame 1), so the atv71 profile names its registers.
    first_answer = frames[7]
    assert first_answer["summary"] == (
        "HR = 0028 0258 01F4 0000 (4 registers): SFr = 4.0 kHz, tFr = 60.0 Hz, HSP = 50.0 Hz, LSP = 0.0 Hz"
    )
    assert [(p["address"], p["code"], p["raw"], p["value"], p["unit"]) for p in first_answer["params"]] == [
        (3102, "SFr", 40, 4.0, "kHz"), (3103, "tFr", 600, 60.0, "Hz"), (3104, "HSP", 500, 50.0, "Hz"),
        (3105, "LSP", 0, 0.0, "Hz"),
    ]
    [device] = [r for r in records if r["kind"] == "device"]
    assert device == {"kind": "device", "index": 1, "slave": 2, "vendor": "Telemecanique",
                      "product_code": "ATV71HU15M3", "revision": "0201", "profile": "atv71", "applied": True}
    # Drive 12 never identified itself: its registers stay unnamed without --profile.
    assert all(p["code"] is None for p in frames[11]["params"])


def test_analyze_mcap_equals_text(cli: Cli) -> None:
    text = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl()[1:]
    binary = cli("analyze", str(SAMPLE_MCAP), "--format", "jsonl").jsonl()[1:]
    assert text == binary


def test_line_override_changes_timing(cli: Cli, tmp_path: Path) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--line", "9600", "8E1")
    assert result.jsonl()[0]["line"] == "9600 8E1"
    quoted = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--line", "115200 8N1", "--char-timing")
    assert quoted.jsonl()[0]["t3_5_s"] == pytest.approx(3.5 * 10 / 115200)


def test_output_file_and_stdin(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "frames.jsonl"
    assert cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "-o", str(out)).code == 0
    import io

    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(SAMPLE_LOG.read_bytes())))
    from_stdin = cli("analyze", "-", "--format", "jsonl")
    assert from_stdin.out.splitlines()[1:] == out.read_text().splitlines()[1:]


def test_convert_both_ways(cli: Cli, tmp_path: Path) -> None:
    mcap = tmp_path / "s.mcap"
    back = tmp_path / "s.log"
    assert cli("convert", str(SAMPLE_LOG), str(mcap)).code == 0
    assert cli("convert", str(mcap), str(back)).code == 0
    assert back.read_bytes() == SAMPLE_LOG.read_bytes()
    refused = cli("convert", str(SAMPLE_LOG), str(mcap))
    assert refused.code == 11 and "add --force" in refused.err
    assert cli("convert", str(SAMPLE_LOG), str(mcap), "--force").code == 0


def test_convert_keeps_late_notes(cli: Cli, tmp_path: Path) -> None:
    source = tmp_path / "n.log"
    source.write_text("# rtu-capture v1\n# line: 9600 8N1\n# timing: host\n# head\n1.0 01\n# tail note\n2.0 02\n")
    assert cli("convert", str(source), str(tmp_path / "n.mcap")).code == 0
    assert cli("convert", str(tmp_path / "n.mcap"), str(tmp_path / "n2.log")).code == 0
    text = (tmp_path / "n2.log").read_text()
    assert "# head\n" in text and "# tail note\n" in text


def test_missing_line_settings_say_how_to_fix(cli: Cli, tmp_path: Path) -> None:
    source = tmp_path / "noline.log"
    source.write_text("# rtu-capture v1\n1.0 01 02\n")
    result = cli("analyze", str(source))
    assert result.code == 10
    assert "--line BAUD FORMAT" in result.err
    assert cli("analyze", str(source), "--line", "9600", "8N1").code == 0


@pytest.mark.parametrize(
    ("args", "code", "words"),
    [
        (["analyze", "/nonexistent/x.log"], 3, "/nonexistent/x.log: no such file"),
        (["analyze", "{tmp}"], 4, "is a directory"),
        (["analyze", "{tmp}/capture.erf"], 5, "cannot tell the capture format"),
        (["analyze", str(SAMPLE_LOG), "--line", "19200", "8Q1"], 2, "--line: line settings '19200 8Q1'"),
        (["analyze", str(SAMPLE_LOG), "--line", "7", "8E1"], 2, "--line: baud rate 7 is outside 50..4000000"),
        (["analyze", str(SAMPLE_LOG), "--response-timeout", "-5"], 2, "give milliseconds from 0 (no limit) to 600000"),
    ],
)
def test_errors_are_one_line_without_traceback(tmp_path: Path, args: list[str], code: int, words: str) -> None:
    (tmp_path / "capture.erf").write_bytes(b"\x00\x11\x22\x33")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    result = subprocess.run(
        [sys.executable, "-m", "sniffer", *argv], capture_output=True, text=True, check=False,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert result.returncode == code, result.stderr
    assert result.stderr.count("\n") == 1
    assert result.stderr.startswith("error: ") and words in result.stderr
    assert "Traceback" not in result.stderr


def test_debug_shows_the_traceback(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "sniffer", "--debug", "analyze", "/nonexistent/x.log"],
        capture_output=True, text=True, check=False,
    )
    assert result.returncode != 0
    assert "Traceback" in result.stderr


def test_unreadable_file(tmp_path: Path, cli: Cli) -> None:
    path = tmp_path / "locked.log"
    path.write_text("# rtu-capture v1\n")
    path.chmod(0)
    if os.geteuid() == 0:
        # root opens any file; reading the own process's memory at offset 0 still fails (EIO)
        path = Path("/proc/self/mem")
    result = cli("analyze", str(path))
    assert result.code == 4 and "cannot read" in result.err


def test_format_recognised_by_content_when_suffix_is_unknown(cli: Cli, tmp_path: Path) -> None:
    for source, name in ((SAMPLE_LOG, "capture.dat"), (SAMPLE_MCAP, "capture.bin")):
        copy = tmp_path / name
        copy.write_bytes(source.read_bytes())
        result = cli("analyze", str(copy), "--format", "jsonl")
        assert result.code == 0, result.err
        assert len(result.jsonl()) == 55  # capture, 52 frames, device, summary


def test_convert_removes_its_output_when_the_input_breaks(cli: Cli, tmp_path: Path) -> None:
    source = tmp_path / "broken.log"
    source.write_text("# rtu-capture v1\n# line: 9600 8N1\n1.0 01 02\n0.5 03\n")
    result = cli("convert", str(source), str(tmp_path / "out.mcap"))
    assert result.code == 8 and "line 4" in result.err
    assert not (tmp_path / "out.mcap").exists()


def test_host_timed_sample_gives_the_same_frames(cli: Cli) -> None:
    exact = [f for f in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl() if f["kind"] == "frame"]
    host_records = cli("analyze", str(CAPTURES / "atv71-plc-poll-usb.log"), "--format", "jsonl").jsonl()
    assert host_records[0]["timing"] == "host"
    host = [f for f in host_records if f["kind"] == "frame"]
    key = ("hex", "role", "crc_ok", "slave", "function", "exception_code")
    assert [tuple(f[k] for k in key) for f in host] == [tuple(f[k] for k in key) for f in exact]
    timing_flags = {"gap_1_5", "short_idle"}
    assert [f["flags"] for f in host] == [[x for x in f["flags"] if x not in timing_flags] for f in exact]
    for h, e in zip(host, exact, strict=True):
        # Host times are read times: later than the wire, by at most the latency timer and jitter.
        assert e["t_end_ns"] <= h["t_end_ns"] <= e["t_end_ns"] + 17_000_000


def test_host_timing_is_said_in_the_table(cli: Cli) -> None:
    out = cli("analyze", str(CAPTURES / "atv71-plc-poll-usb.log")).out
    assert "timing host" in out and "times are when the PC read the bytes" in out


def test_timing_override(cli: Cli) -> None:
    records = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--timing", "host").jsonl()
    assert records[0]["timing"] == "host"
    frames = [f for f in records if f["kind"] == "frame"]
    assert len(frames) == 52 and not any({"gap_1_5", "short_idle"} & set(f["flags"]) for f in frames)


def test_filters(cli: Cli) -> None:
    def indices(*filters: str) -> list[int]:
        args = [x for f in filters for x in ("--filter", f)]
        records = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", *args).jsonl()
        assert records[-1]["kind"] == "summary" and records[-1]["frames"] == 52  # the summary covers all frames
        return [r["index"] for r in records if r["kind"] == "frame"]

    assert indices("slave=3") == [12, 19, 32, 39, 51]
    assert indices("slave=3", "flag=timeout") == [12, 19, 32, 39]
    assert indices("role=exception") == [31, 41]
    assert indices("slave=4", "slave=12", "role=exception") == [31, 41]
    assert indices("function=8") == [42, 43]
    assert indices("flag=gap_1_5", "flag=short_idle") == [36, 47]


@pytest.mark.parametrize(
    ("spec", "words"),
    [("slave=300", "slave must be a number from 0 to 247"), ("role=master", "role is one of request, response"),
     ("flag=late", "flag is one of gap_1_5"), ("colour=red", "KEY one of slave, function, role, flag")],
)
def test_bad_filters_say_what_is_allowed(cli: Cli, spec: str, words: str) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--filter", spec)
    assert result.code == 2 and words in result.err


def test_stats_json(cli: Cli) -> None:
    result = cli("stats", str(SAMPLE_LOG), "--format", "json")
    assert result.code == 0, result.err
    import json

    stats = json.loads(result.out)
    assert (stats["frames"], stats["crc_errors"], stats["noise_bytes"]) == (52, 1, 1)
    assert stats["roles"] == {"exception": 2, "noise": 1, "request": 28, "response": 21}
    rows = {(r["slave"], r["function"]): r for r in stats["per_slave_function"]}
    absent = rows[(3, 3)]
    assert (absent["requests"], absent["responses"], absent["timeouts"], absent["retries"]) == (5, 0, 4, 4)
    assert rows[(12, 3)]["exceptions"] == {"2": 1}
    assert rows[(4, 16)]["exceptions"] == {"4": 1}
    drive2 = rows[(2, 3)]
    assert (drive2["requests"], drive2["responses"], drive2["crc_errors"], drive2["retries"]) == (6, 6, 1, 1)
    assert 0.002 < drive2["latency_s"]["min"] <= drive2["latency_s"]["p50"] <= drive2["latency_s"]["max"] < 0.006
    assert drive2["poll_period_s"]["p50"] == pytest.approx(0.093, abs=0.005)
    assert rows[(20, 23)]["short_idle"] == 1 and rows[(20, 23)]["gap_1_5"] == 1
    assert 0.05 < stats["bus_load"] < 0.3


def test_stats_table(cli: Cli) -> None:
    out = cli("stats", str(SAMPLE_LOG)).out
    assert "bus_load" in out and "Read/Write Multiple Registers" in out and "02×1" in out


def test_jsonl_is_what_the_standard_json_module_writes(cli: Cli) -> None:
    """orjson encodes the records; its output must stay byte for byte the stdlib's compact JSON."""
    for sample in sorted(CAPTURES.glob("*.log")):
        lines = cli("analyze", str(sample), "--format", "jsonl").out.splitlines()
        assert lines
        for line in lines:
            assert line == json.dumps(json.loads(line), ensure_ascii=False, separators=(",", ":"))


def test_the_objects_left_are_frozen_before_the_interpreter_exits(monkeypatch: pytest.MonkeyPatch) -> None:
    """The exit code is kept, and the interpreter's last collections skip what the run left
    (a noticeable wait after a long export)."""
    monkeypatch.setattr(rtusniff_cli, "main", lambda: 3)
    frozen = gc.get_freeze_count()
    try:
        with pytest.raises(SystemExit) as exited:
            rtusniff_cli.entry_point()
        assert exited.value.code == 3
        assert gc.get_freeze_count() > frozen
    finally:
        gc.unfreeze()


@pytest.mark.parametrize(("args", "said"), [
    (["analyze", "CAPTURE", "--bogus"], "error: rtusniff analyze: unrecognized arguments: --bogus "
                                        "('rtusniff analyze --help' lists the options)"),
    (["stats", "CAPTURE", "--format", "xml"], "error: rtusniff stats: argument --format: invalid choice: 'xml'"),
    (["wireshark", "setup", "--nope"], "error: rtusniff wireshark setup: unrecognized arguments: --nope"),
    (["analyze"], "error: rtusniff analyze: the following arguments are required: CAPTURE"),
    (["bogus"], "error: rtusniff: argument COMMAND: invalid choice: 'bogus'"),
])
def test_a_wrong_argument_is_one_line_naming_its_command(args: list[str], said: str) -> None:
    """Not the usage of every option, not the top level's for a command's option: one line, the
    command's name and where its options are listed; exit code 2."""
    words = [str(SAMPLE_LOG) if word == "CAPTURE" else word for word in args]
    result = subprocess.run([sys.executable, "-m", "sniffer", *words], capture_output=True, text=True, timeout=60,
                            check=False)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(said), result.stderr


def test_values_narrows_with_a_filter(cli: Cli) -> None:
    """``values --filter`` keeps the values of the frames the filter keeps, as ``analyze`` does."""
    filtered = cli("values", str(SAMPLE_LOG), "--filter", "slave=12", "--format", "jsonl").jsonl()
    by_slave = cli("values", str(SAMPLE_LOG), "--slave", "12", "--format", "jsonl").jsonl()
    assert filtered == by_slave and filtered
    frames = {r["index"] for r in cli("analyze", str(SAMPLE_LOG), "--filter", "slave=12", "--format",
                                      "jsonl").jsonl() if r["kind"] == "frame"}
    assert {row["index"] for row in filtered} <= frames
