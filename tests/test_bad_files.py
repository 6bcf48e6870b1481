"""Every kind of bad capture file the field sends us: one line naming file and place, its own exit code."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import SAMPLE_MCAP, CliResult, write_foreign_mcap

Cli = Callable[..., CliResult]
HEADER = "# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n"


def corrupted_mcap(path: Path) -> None:
    damaged = bytearray(SAMPLE_MCAP.read_bytes())
    for offset in range(300, len(damaged) - 100, 37):
        damaged[offset] ^= 0x5A
    path.write_bytes(damaged)


Content = bytes | Callable[[Path], None]
BAD_FILES: list[tuple[str, str, Content, int, str]] = [
    ("empty", "c.log", b"", 6, "c.log:line 1: empty file"),
    ("header only", "c.log", HEADER.encode(), 14, "c.log: the capture holds no bytes"),
    ("missing header", "c.log", b"1.0 01 02\n", 6, "c.log:line 1: missing header"),
    ("wrong header", "c.log", b"# rtu-capture v7\n1.0 01\n", 5, "c.log:line 1: unknown format version v7"),
    ("bad hex", "c.log", (HEADER + "1.0 01 ZZ\n").encode(), 7, "c.log:line 4: bad hex digit 'Z'"),
    ("odd hex digits", "c.log", (HEADER + "1.0 01 0\n").encode(), 7, "c.log:line 4: odd number of hex digits"),
    ("decreasing times", "c.log", (HEADER + "2.0 01\n1.0 02\n").encode(), 8, "c.log:line 5: time 1.000000000"),
    ("time beyond 2262", "c.log", (HEADER + "17004010417.0 02\n").encode(), 7,
     "c.log:line 4: time 17004010417.0 is beyond"),
    ("binary garbage", "c.log", HEADER.encode() + b"\x89PNG\r\n\x1a\n\x00\xff", 7, "c.log:line 4: not text"),
    ("MCAP cut before its first block", "c.mcap", SAMPLE_MCAP.read_bytes()[:800], 14,
     "c.mcap: the capture holds no bytes"),
    ("corrupted MCAP", "c.mcap", corrupted_mcap, 9, "c.mcap:byte 47: damaged MCAP"),
    ("not an MCAP", "c.mcap", HEADER.encode(), 9, "c.mcap:byte 0"),
    ("MCAP from another tool", "c.mcap", write_foreign_mcap, 9, "c.mcap:byte 138: not an rtusniff capture"),
    ("unknown format", "c.erf", b"\x00\x11\x22\x33\x1c\x00\x00\x00", 5, "c.erf: cannot tell the capture format"),
]


@pytest.mark.parametrize("bad", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_file(cli: Cli, tmp_path: Path, bad: tuple[str, str, Content, int, str]) -> None:
    name, file_name, content, code, words = bad
    path = tmp_path / file_name
    if callable(content):
        content(path)
    else:
        path.write_bytes(content)
    commands = (["stats"], *(["analyze", "--jobs", jobs] for jobs in ("1", "2")),
                *(["export", "--rrd", str(tmp_path / "out.rrd"), "--force", "--jobs", jobs] for jobs in ("1", "2")))
    for command in commands:  # jobs 2: read in the decoding process
        result = cli(command[0], str(path), *command[1:])
        assert result.code == code, f"{name}: {result.err}"
        error_lines = [line for line in result.err.splitlines() if line.startswith("error: ")]
        assert len(error_lines) == 1 and words in error_lines[0], result.err
        assert str(tmp_path) in error_lines[0]
        assert "Traceback" not in result.err
        if command[0] == "stats":  # nothing but the error: no table of nothing before it
            assert result.out == "", result.out



def test_huge_gap_is_analysed_not_refused(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "gap.log"
    # A request, then its answer a year later (a capture left running across a site shutdown).
    path.write_text(HEADER + "1.0 02 03 0C 81 00 01 D7 41\n31536001.0 02 03 02 00 05 3C 47\n")
    records = cli("analyze", str(path), "--format", "jsonl").jsonl()
    frames = [r for r in records if r["kind"] == "frame"]
    assert [f["role"] for f in frames] == ["request", "response"]
    assert "timeout" in frames[0]["flags"] and "unexpected" in frames[1]["flags"]
    assert records[-1]["duration_s"] == pytest.approx(31536000, abs=1)



def _every_readable_format() -> list[str]:
    from sniffer.io.registry import formats_for

    return sorted(formats_for("read"))


@pytest.mark.parametrize("name", _every_readable_format())
@pytest.mark.parametrize("damage", ["empty", "cut in half", "garbage after the first bytes"])
def test_every_format_refuses_a_broken_file_in_one_line(cli: Cli, tmp_path: Path, name: str, damage: str) -> None:
    """Whatever format is registered: a broken file of it is one error line naming the file,
    with a documented exit code, never a traceback (a file cut short may still read: a
    recording cut short is data)."""
    from sniffer.io.registry import all_formats, open_reader, open_writer
    from tests.conftest import SAMPLE_LOG

    fmt = all_formats()[name]
    whole = tmp_path / f"whole{fmt.suffixes[0]}"
    reader = open_reader(str(SAMPLE_LOG))
    if fmt.open_writer is not None:
        writer = open_writer(str(whole), reader.info, name)
        for batch in reader.batches():
            writer.write_batch(batch)
        writer.close()
    reader.close()
    original = whole.read_bytes() if whole.exists() else b""
    broken = {"empty": b"", "cut in half": original[: len(original) // 2],
              "garbage after the first bytes": original[:20] + bytes(range(256)) * 4}[damage]
    path = tmp_path / f"broken{fmt.suffixes[0]}"
    path.write_bytes(broken)
    result = cli("analyze", str(path), "--format", "jsonl", "-o", str(tmp_path / "out.jsonl"))
    error_lines = [line for line in result.err.splitlines() if line.startswith("error: ")]
    assert "Traceback" not in result.err
    if damage == "cut in half" and result.code == 0:
        return
    assert result.code in (5, 6, 7, 8, 9, 14), result.err
    assert len(error_lines) == 1 and str(path) in error_lines[0], result.err


def test_a_time_of_thousands_of_digits_is_one_short_line(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "long.log"
    path.write_text(f"# rtu-capture v1\n# line: 19200 8E1\n{'9' * 5000}.5 01 03\n")
    result = cli("analyze", str(path))
    assert result.code == 7 and f"{path}:line 3: bad time" in result.err and len(result.err) < 300


def test_standard_input_takes_text_only(tmp_path: Path) -> None:
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", "-", "--input-format", "mcap"],
                            stdin=SAMPLE_MCAP.open("rb"), capture_output=True, text=True, check=False)
    assert result.returncode == 2 and "standard input carries the text format only" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_disk_on_standard_output_is_exit_11() -> None:
    import subprocess
    import sys

    with open("/dev/full", "w") as full:
        result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", str(SAMPLE_MCAP)], stdout=full,
                                stderr=subprocess.PIPE, text=True, check=False)
    assert result.returncode == 11
    assert result.stderr.strip() == "error: cannot write the output: No space left on device"


@pytest.mark.parametrize("suffix", [".log", ".mcap"])
def test_a_capture_cut_short_anywhere_reads_up_to_the_cut(cli: Cli, tmp_path: Path, suffix: str) -> None:
    """A copy or a recording cut short at any byte: what came before the cut is read, with a
    warning naming where; only a cut inside the header is an error (docs/capture-formats.md)."""
    from tests.conftest import SAMPLE_LOG

    original = (SAMPLE_LOG if suffix == ".log" else SAMPLE_MCAP).read_bytes()
    whole = len([r for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl() if r["kind"] == "frame"])
    path = tmp_path / f"cut{suffix}"
    read = 0
    for percent in range(1, 100):
        cut = original[: len(original) * percent // 100]
        path.write_bytes(cut)
        result = cli("analyze", str(path), "--format", "jsonl")
        assert "Traceback" not in result.err
        if result.code == 0:
            read += 1
            frames = [r for r in result.jsonl() if r["kind"] == "frame"]
            # Text cut right after a newline is whole lines: nothing to tell it from a shorter capture.
            said = "cut short" in result.err or (suffix == ".log" and cut.endswith(b"\n"))
            assert len(frames) <= whole and said, result.err
        else:
            errors = [line for line in result.err.splitlines() if line.startswith("error: ")]
            assert result.code in (6, 9, 14) and len(errors) == 1, result.err
    assert read >= (85 if suffix == ".log" else 25)
