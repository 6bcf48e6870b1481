"""``rtusniff cut``: the cut of a window reads back to the window's frames with their times
unchanged (exact and host captures, text and MCAP, a logic analyzer's session with two probes),
never starts or ends inside a frame, and says where it came from."""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import ROOT, CliResult
from tests.real_recordings import REAL

Cli = Callable[..., CliResult]
CAPTURES = ROOT / "captures"


def frames(cli: Cli, *argv: str) -> list[tuple[str, int, int, bool]]:
    result = cli("analyze", *argv, "--format", "jsonl")
    assert result.code == 0, result.err
    return [(r["hex"], r["t_ns"], r["t_end_ns"], r["crc_ok"]) for r in result.jsonl() if r["kind"] == "frame"]


def window_in(cli: Cli, cut: Path) -> list[tuple[str, int, int, bool]]:
    """The frames of a cut that are its window: a cut may hold frames of context around it, and
    its frames keep their numbers, so the window is the frames its note names ("frames #K..#J")."""
    records = cli("analyze", str(cut), "--format", "jsonl").jsonl()
    found = [re.search(r"frames #(\d+)\.\.#(\d+) \(numbered as there\)", note) for note in records[0]["notes"]]
    first, last = [(int(m.group(1)), int(m.group(2))) for m in found if m][-1]
    return [(r["hex"], r["t_ns"], r["t_end_ns"], r["crc_ok"]) for r in records
            if r["kind"] == "frame" and first <= r["index"] <= last]


def test_a_cut_keeps_the_numbers_of_its_frames(cli: Cli, tmp_path: Path) -> None:
    """A ticket's "#25" is #25 in the attachment: the cut's frames are numbered as in the capture
    they were cut from, in text and in MCAP, and its window options use those numbers."""
    sample = str(CAPTURES / "atv71-plc-poll.log")
    whole = {r["index"]: r["hex"] for r in cli("analyze", sample, "--format", "jsonl").jsonl() if r["kind"] == "frame"}
    for suffix in (".log", ".mcap"):
        out = tmp_path / f"cut{suffix}"
        assert cli("cut", sample, "--around", "25", "--context", "3", "-o", str(out)).code == 0
        records = [r for r in cli("analyze", str(out), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
        assert records[0]["index"] > 0 and all(whole[r["index"]] == r["hex"] for r in records)
        answered = [r for r in records if r["request_index"] is not None]
        assert answered and all(whole[r["request_index"]] for r in answered)
        around = [r for r in cli("analyze", str(out), "--around", "25", "--context", "0", "--format",
                                 "jsonl").jsonl() if r["kind"] == "frame"]
        assert [r["index"] for r in around] == [25]
        again = tmp_path / f"again{suffix}"  # converted, it keeps them
        assert cli("convert", str(out), str(again)).code == 0
        assert [r["index"] for r in cli("analyze", str(again), "--format", "jsonl").jsonl()
                if r["kind"] == "frame"] == [r["index"] for r in records]


CASES = [
    ("atv71-plc-poll.log", ["--around", "25", "--context", "3"], ".log"),
    ("atv71-plc-poll.mcap", ["--from", "1s", "--to", "2s"], ".mcap"),
    ("atv71-plc-poll-usb.log", ["--around", "30", "--context", "5"], ".log"),
    ("xbt-hmi.log", ["--limit", "9"], ".mcap"),
    ("nord-uss.log", ["--around", "4", "--context", "2"], ".log"),
]


@pytest.mark.parametrize(("sample", "window", "suffix"), CASES, ids=[c[0] for c in CASES])
def test_a_cut_reads_back_to_the_window(cli: Cli, tmp_path: Path, sample: str, window: list[str],
                                        suffix: str) -> None:
    out = tmp_path / f"cut{suffix}"
    result = cli("cut", str(CAPTURES / sample), *window, "-o", str(out))
    assert result.code == 0, result.err
    expected = frames(cli, str(CAPTURES / sample), *window)
    got = window_in(cli, out)
    assert [f[0] for f in got] == [f[0] for f in expected] and len(got) >= 5
    timed = cli("analyze", str(out), "--format", "jsonl").jsonl()[0]["timing"] == "exact"
    if timed:  # exact timing: every time unchanged
        assert got == expected
    digest = hashlib.sha256((CAPTURES / sample).read_bytes()).hexdigest()
    notes = cli("analyze", str(out), "--format", "jsonl").jsonl()[0]["notes"]
    assert any(f"sha256 {digest}" in note and "frames #" in note for note in notes)
    assert f"wrote {out}: frames #" in result.err


def test_a_cut_inside_a_read_keeps_whole_frames(cli: Cli, tmp_path: Path) -> None:
    """Host reads that hold the end of one frame and the start of the next are cut between them."""
    text = "\n".join(["# rtu-capture v1", "# line: 19200 8E1", "# timing: host",
                      "1700000000.010000000 02 03 0C 1E 00 04 27 6C 02 03",
                      "1700000000.020000000 08 00 28 02 58 01 F4 00 00 52 B0 02 03 0C",
                      "1700000000.030000000 1E 00 04 27 6C",
                      "1700000000.200000000 02 03 08 00 28 02 58 01 F4 00 00 52 B0",
                      ""])
    source = tmp_path / "reads.log"
    source.write_text(text)
    answer, request = "0203080028025801f4000052b0", "02030c1e0004276c"
    for around, context, expected in [("1", "0", [answer]), ("2", "1", [answer, request, answer])]:
        out = tmp_path / f"cut-{around}.log"
        assert cli("cut", str(source), "--around", around, "--context", context, "-o", str(out)).code == 0
        got = window_in(cli, out)
        assert [f[0] for f in got] == expected and all(f[3] for f in got)
    # The reads at the edges were cut between frames; a part that lost the bytes after it ends that
    # many characters before its read (three of 0.573 ms), as the framer timed its bytes in the whole.
    lines = [line for line in (tmp_path / "cut-1.log").read_text().splitlines() if not line.startswith("#")]
    # The answer's request (#0) comes along as context, so that the answer pairs as in the whole.
    assert lines == ["1700000000.010000000 02 03 0C 1E 00 04 27 6C 02 03",
                     "1700000000.018281250 08 00 28 02 58 01 F4 00 00 52 B0"]
    whole = cli("analyze", str(source), "--format", "jsonl").jsonl()[2]
    assert cli("analyze", str(tmp_path / "cut-1.log"), "--format", "jsonl").jsonl()[2]["t_end_ns"] == whole["t_end_ns"]


@pytest.mark.skipif(not (REAL / "sigrok").exists(), reason="../shared/real is not beside the checkout")
def test_a_cut_of_a_two_probe_session(cli: Cli, tmp_path: Path) -> None:
    session = REAL / "sigrok" / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    options = ["--line", "19200", "8E1", "--channel", "0", "--channel", "1"]
    out = tmp_path / "cut.log"
    assert cli("cut", str(session), *options, "--around", "10", "--context", "4", "-o", str(out)).code == 0
    assert frames(cli, str(out)) == frames(cli, str(session), *options, "--around", "10", "--context", "4")
    assert "# channels: 0 1" in out.read_text()


def test_cut_refuses_what_it_cannot_do(cli: Cli, tmp_path: Path) -> None:
    sample = str(CAPTURES / "atv71-plc-poll.log")
    no_window = cli("cut", sample, "-o", str(tmp_path / "a.log"))
    assert no_window.code == 2 and "cut needs a window" in no_window.err
    empty = cli("cut", sample, "--from", "23:59:59", "-o", str(tmp_path / "b.log"))
    assert empty.code == 14 and not (tmp_path / "b.log").exists()
    assert empty.err.strip() == (f"error: {sample}: no frame falls in the window of --from/--to/--around: the "
                                 "capture's 52 frames run from 2023-11-14 22:13:20.000 to 2023-11-14 22:13:22.659 UTC "
                                 "(#0 to #51); nothing to cut")
    existing = tmp_path / "c.log"
    existing.write_text("keep")
    refused = cli("cut", sample, "--limit", "3", "-o", str(existing))
    assert refused.code != 0 and existing.read_text() == "keep"
    into_itself = cli("cut", sample, "--limit", "3", "-o", sample, "--force")
    assert into_itself.code != 0 and (CAPTURES / "atv71-plc-poll.log").read_text().startswith("# rtu-capture v1")


def test_an_exact_chunk_cut_ends_its_characters_earlier(cli: Cli, tmp_path: Path) -> None:
    """Two frames back to back in one exact chunk: the cut keeps the first, ending 13 character
    times (19200 8E1: 572 917 ns each) before the chunk, its times as in the whole."""
    source = tmp_path / "joined.log"
    source.write_text("# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n"
                      "1700000000.020000000 02 03 0C 1E 00 04 27 6C 02 03 08 00 28 02 58 01 F4 00 00 52 B0\n"
                      "1700000000.100000000 02 03 0C 1E 00 04 27 6C\n")
    out = tmp_path / "first.log"
    assert cli("cut", str(source), "--limit", "1", "-o", str(out)).code == 0
    [line] = [line for line in out.read_text().splitlines() if not line.startswith("#")]
    assert line == f"1700000000.{20_000_000 - round(13 * 1e9 * 11 / 19200):09d} 02 03 0C 1E 00 04 27 6C"
    assert frames(cli, str(out)) == frames(cli, str(source), "--limit", "1")


def test_a_cut_that_begins_mid_exchange_takes_context_or_says_so(cli: Cli, tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Frames #36..#46 of the sample begin with an answer whose request is #35 and hold a retry
    whose first attempt is before #36: the cut takes the frames before them that make it decode
    as the whole capture did, and its note says where the window is (issue 66). Where no such
    context is searched (a window too long), it says what it splits, in its note and a warning."""
    sample = str(ROOT / "captures" / "atv71-plc-poll.log")
    out = tmp_path / "cut.log"
    result = cli("cut", sample, "--around", "41", "--context", "5", "-o", str(out))
    assert result.code == 0 and "with 4 frame(s) before and 0 after" in result.err, result.err
    whole = [r for r in cli("analyze", sample, "--format", "jsonl").jsonl() if r["kind"] == "frame"][36:47]
    cut = [r for r in cli("analyze", str(out), "--format", "jsonl").jsonl() if r["kind"] == "frame"][4:15]
    assert [(r["hex"], r["role"], r["flags"], r["latency_s"]) for r in cut] == \
        [(r["hex"], r["role"], r["flags"], r["latency_s"]) for r in whole]
    assert [r["request_index"] for r in cut][:1] == [whole[0]["request_index"]]  # numbered as in the whole
    monkeypatch.setattr("sniffer.commands.cut.SEARCHED_FRAMES", 0)
    said = ("the cut begins mid-exchange: 1 answer whose request lies before it and 1 retry whose first attempt "
            "lies before it")
    result = cli("cut", sample, "--around", "41", "--context", "5", "-o", str(tmp_path / "alone.log"))
    assert result.code == 0 and f"warning: {tmp_path / 'alone.log'}: {said}" in result.err, result.err
    assert said in (tmp_path / "alone.log").read_text()


@pytest.mark.parametrize("value", ["x", "-3", "1e5", "12345678901234567890", "5\n# first-frame: 6"])
def test_a_bad_first_frame_header_is_one_line(cli: Cli, tmp_path: Path, value: str) -> None:
    capture = tmp_path / "bad.log"
    capture.write_text(f"# rtu-capture v1\n# line: 19200 8E1\n# first-frame: {value}\n"
                       "1700000000.100000000 02 03 0C 1E 00 04 27 6C\n")
    result = cli("analyze", str(capture))
    assert result.code == 6 and result.err.count("\n") == 1 and str(capture) in result.err, result.err
    assert "first-frame" in result.err
