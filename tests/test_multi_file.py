"""Several capture files as one capture: rotated recordings, in time order, refused when they
overlap or disagree on the line."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import SAMPLE_LOG, CliResult

Cli = Callable[..., CliResult]


def split(tmp_path: Path, cut: int, *, line: str = "19200 8E1", names: tuple[str, str] = ("a.log", "b.log")
          ) -> tuple[Path, Path]:
    """The sample's text capture cut after its ``cut``-th data line into two files, as a
    recorder's rotation would."""
    lines = SAMPLE_LOG.read_text().splitlines()
    header = [text for text in lines if text.startswith("#")]
    data = [text for text in lines if not text.startswith("#")]
    first, second = tmp_path / names[0], tmp_path / names[1]
    first.write_text("\n".join(header + data[:cut]) + "\n")
    other = [text.replace("19200 8E1", line) for text in header]
    second.write_text("\n".join(other + data[cut:]) + "\n")
    return first, second


def records(result: CliResult) -> list[dict[str, object]]:
    assert result.code == 0, result.err
    return result.jsonl()


@pytest.mark.parametrize("cut", [1, 20, 52])
def test_split_files_read_as_the_whole(cli: Cli, tmp_path: Path, cut: int) -> None:
    whole = records(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl"))
    first, second = split(tmp_path, cut)
    for order in ((first, second), (second, first)):  # named in any order: read in time order
        joined = records(cli("analyze", *map(str, order), "--format", "jsonl"))
        frames = [r for r in joined if r["kind"] == "frame"]
        assert [(f["t_ns"], f["hex"], f["role"], f["request_index"]) for f in frames] == \
            [(f["t_ns"], f["hex"], f["role"], f["request_index"]) for f in whole if f["kind"] == "frame"]
        assert joined[0]["source"] == " + ".join(map(str, order))
        assert joined[-1]["frames"] == whole[-1]["frames"]
    stats = json.loads(cli("stats", str(second), str(first), "--format", "json").out)
    assert stats["frames"] == 52


def test_a_frame_split_between_two_files_is_one_frame(cli: Cli, tmp_path: Path) -> None:
    """A rotation can fall inside a frame: the next file completes it."""
    lines = SAMPLE_LOG.read_text().splitlines()
    header = [text for text in lines if text.startswith("#")]
    data = [text for text in lines if not text.startswith("#")]
    stamp, *octets = data[2].split()  # 14 03 31 9D 00 08 D9 DB, cut after four bytes
    first, second = tmp_path / "r-0001.log", tmp_path / "r-0002.log"
    first.write_text("\n".join([*header, *data[:2], f"{int(stamp.split('.')[0])}.{stamp.split('.')[1][:-3]}000 "
                                + " ".join(octets[:4])]) + "\n")
    second.write_text("\n".join([*header, f"{stamp} " + " ".join(octets[4:]), *data[3:]]) + "\n")
    frames = [r for r in records(cli("analyze", str(first), str(second), "--format", "jsonl")) if r["kind"] == "frame"]
    assert frames[2]["hex"] == "1403319d0008d9db" and frames[2]["crc_ok"] is True
    assert len(frames) == 52


def test_overlapping_files_are_refused(cli: Cli, tmp_path: Path) -> None:
    first, _ = split(tmp_path, 30)
    result = cli("analyze", str(SAMPLE_LOG), str(first))
    assert result.code == 8 and result.out == ""
    assert "the files overlap" in result.err and len(result.err.strip().splitlines()) == 1


def test_files_of_other_lines_or_timings_are_refused(cli: Cli, tmp_path: Path) -> None:
    first, second = split(tmp_path, 20, line="9600 8N1")
    result = cli("analyze", str(first), str(second))
    assert result.code == 6 and "line 9600 8N1, but" in result.err and str(second) in result.err
    assert cli("analyze", str(first), str(second), "--line", "19200 8E1", "-o", str(tmp_path / "x.txt")).code == 0
    host = tmp_path / "host.log"
    host.write_text(second.read_text().replace("# timing: exact", "# timing: host").replace("9600 8N1", "19200 8E1"))
    timing = cli("analyze", str(first), str(host))
    assert timing.code == 6 and "timing host, but" in timing.err


def test_standard_input_is_a_capture_of_its_own(cli: Cli) -> None:
    result = cli("analyze", "-", str(SAMPLE_LOG))
    assert result.code == 2 and "standard input" in result.err


def test_export_of_rotated_files_is_one_recording(cli: Cli, tmp_path: Path) -> None:
    first, second = split(tmp_path, 26)
    out = tmp_path / "joined.mcap"
    assert cli("export", str(first), str(second), "--mcap", str(out)).code == 0
    again = records(cli("analyze", str(out), "--format", "jsonl"))
    whole = records(cli("analyze", str(SAMPLE_LOG), "--format", "jsonl"))
    assert [f["hex"] for f in again if f["kind"] == "frame"] == [f["hex"] for f in whole if f["kind"] == "frame"]
