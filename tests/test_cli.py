"""``rtusniff analyze`` and ``convert`` as a user runs them."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, SAMPLE_LOG, SAMPLE_MCAP, CliResult

Cli = Callable[..., CliResult]
FRAME_FIELDS = {
    "kind": str, "index": int, "t": float, "t_end": float, "hex": str, "crc_ok": bool, "slave": (int, type(None)),
    "function": (int, type(None)), "role": str, "exception_code": (int, type(None)), "flags": list,
    "request_index": (int, type(None)), "latency_s": (float, type(None)), "params": list, "summary": str,
}


def test_analyze_table_shows_every_frame(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG))
    assert result.code == 0, result.err
    assert "line 19200 8E1  timing exact" in result.out
    assert "02 03 08 00 28 02 50 01 f4 00 00 52 b0" in result.out  # the damaged response
    assert "gap_1_5" in result.out
    assert result.out.rstrip().endswith(
        "48 frames, 26 request, 19 response, 2 exception, 1 noise, 1 CRC errors, 1 gap_1_5, 1 short_idle"
    )


def test_analyze_jsonl_follows_the_contract(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl")
    assert result.code == 0, result.err
    records = result.jsonl()
    assert records[0]["kind"] == "capture" and records[0]["timing"] == "exact"
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
    assert [f["flags"] for f in frames if f["flags"]] == [["gap_1_5"], ["short_idle"]]
    [noise] = [f for f in frames if f["role"] == "noise"]
    assert (noise["hex"], noise["crc_ok"], noise["slave"], noise["function"]) == ("00", False, None, None)
    assert all(f["request_index"] is None and f["latency_s"] is None and f["params"] == [] for f in frames)


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
        (["analyze", "{tmp}/capture.pcapng"], 5, "cannot tell the capture format"),
        (["analyze", str(SAMPLE_LOG), "--line", "19200", "8Q1"], 2, "--line: line settings '19200 8Q1'"),
    ],
)
def test_errors_are_one_line_without_traceback(tmp_path: Path, args: list[str], code: int, words: str) -> None:
    (tmp_path / "capture.pcapng").write_bytes(b"\x0a\x0d\x0d\x0a")
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
        assert len(result.jsonl()) == 49


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
    assert all(f["flags"] == [] for f in host)
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
    assert len(frames) == 48 and not any(f["flags"] for f in frames)
