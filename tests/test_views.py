"""The terminal views as engineers use them: every width, a pipe, dates, time modes.

Golden screens (tests/golden/screens/) are the shipped sample laid out for 80, 120 and 200
columns: ``RTUSNIFF_REGENERATE_GOLDEN=1`` rewrites them after a deliberate change (review the diff).
"""

from __future__ import annotations

import io
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from rich.console import Console

from decoders.capture import TimingQuality
from sniffer.io.registry import open_reader
from sniffer.pipeline import Analysis, analyze
from sniffer.views.clock import Clock
from sniffer.views.layout import note_lines
from sniffer.views.live import LiveState, LiveView
from sniffer.views.table import PlainTableView
from tests.conftest import ROOT, SAMPLE_LOG, CliResult

GOLDEN = ROOT / "tests" / "golden" / "screens"
REGENERATE = os.environ.get("RTUSNIFF_REGENERATE_GOLDEN") == "1"
SCREENS = [(80, 24), (120, 40), (200, 50)]
Cli = Callable[..., CliResult]
#: A plain line: index, time, Δt, slave, fc, role, req, lat, len, CRC, flags, then the summary.
PLAIN_FIELDS = 11


def check_golden(name: str, text: str) -> None:
    path = GOLDEN / name
    if REGENERATE:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    assert path.read_text() == text, f"{name} differs; RTUSNIFF_REGENERATE_GOLDEN=1 rewrites it"


def fixed_cells(line: str) -> list[str]:
    return line.split()


#: The sample as the README names it (the golden screens show the name: no checkout's path).
SAMPLE = str(SAMPLE_LOG.relative_to(ROOT))


@pytest.fixture
def in_checkout(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)


@pytest.mark.parametrize(("width", "height"), SCREENS)
def test_analyze_screens(cli: Cli, width: int, height: int, in_checkout: None) -> None:
    result = cli("analyze", SAMPLE, "--width", str(width))
    assert result.code == 0, result.err
    lines = result.out.splitlines()
    assert max(map(len, lines[2:])) <= width  # the heading lines wrap as the terminal wraps them
    header = next(line for line in lines if "time (UTC)" in line)
    # The request and latency keep their place; at 80 columns the summary goes below its row.
    for title in ("#", "time (UTC)", "Δt ms", "slave", "fc", "role", "req", "lat ms", "CRC", "flags"):
        assert title in header, (width, title)
    assert ("summary" in header) == (width > 80)
    assert "short_idle" in result.out and "VendorName='Telemecanique'," in result.out  # never split inside
    assert ("hex" in header) == (width >= 200)
    # Numbers are never cut, words never broken where a space was near: every frame's time,
    # Δt and CRC appear whole on its first line.
    assert "…" not in result.out.replace("… (+", "")
    frame_lines = [line for line in lines if re.match(r"^\s*\d+ \s*\d\d:\d\d:\d\d\.\d{6}", line)]
    assert len(frame_lines) == 52
    assert any("1000.000" in line for line in frame_lines)
    check_golden(f"analyze-{width}.txt", result.out)


def test_summary_wraps_at_whole_words(cli: Cli) -> None:
    out = cli("analyze", str(SAMPLE_LOG), "--width", "120").out
    summary_at = out.splitlines()[2].index("summary")
    pieces = [line[summary_at:] for line in out.splitlines()[3:] if len(line) > summary_at]
    words = set(" ".join(pieces).split())
    # "LSP = 0.0 Hz" is written in words that each stay whole on some line.
    for word in ("SFr", "4.0", "kHz,", "LSP", "Hz"):
        assert word in words


def test_pipe_is_one_line_per_frame_with_fixed_fields(cli: Cli) -> None:
    result = cli("analyze", str(SAMPLE_LOG))
    lines = result.out.splitlines()
    rows = [line for line in lines if not line.startswith("#")]
    assert len(rows) == 52
    for row in rows:
        fields = row.split(None, PLAIN_FIELDS)
        assert len(fields) == PLAIN_FIELDS + 1, row
        assert re.fullmatch(r"\d\d:\d\d:\d\d\.\d{6}", fields[1])
        assert fields[9] in ("ok", "BAD", "-")
    # awk picks a column: the slaves of every request.
    requests = [row.split()[3] for row in rows if row.split()[5] == "request"]
    assert requests[:3] == ["2", "20", "20"]
    hexed = [line for line in cli("analyze", str(SAMPLE_LOG), "--hex").out.splitlines() if not line.startswith("#")]
    assert all(re.fullmatch(r"[0-9a-f]+", row.split(None, PLAIN_FIELDS + 1)[11]) for row in hexed)
    # A profile's remarks follow the summary, as on a terminal: the identification, a damaged frame.
    summaries = [row.split(None, PLAIN_FIELDS)[PLAIN_FIELDS] for row in rows]
    assert summaries[1].endswith("⚠ slave 2 is ATV71HU15M3: decoded with profile atv71")
    assert "⚠" in summaries[25]


@pytest.mark.parametrize(("width", "height"), SCREENS)
def test_stats_screens(cli: Cli, width: int, height: int, in_checkout: None) -> None:
    result = cli("stats", SAMPLE, "--width", str(width))
    assert result.code == 0, result.err
    assert max(map(len, result.out.splitlines())) <= width
    for title in ("slave", "fc", "req", "resp", "exc", "CRC", "timeout", "p50", "max"):
        assert title in result.out
    check_golden(f"stats-{width}.txt", result.out)


def test_stats_pipe_rows_split_into_fields(cli: Cli) -> None:
    out = cli("stats", str(SAMPLE_LOG)).out
    bus = dict(line.split() for line in out.split("\n\n")[0].splitlines()[1:])
    assert bus["frames"] == "52" and bus["crc_errors"] == "1" and bus["flag_timeout"] == "4"


def live_screen(width: int, height: int) -> str:
    reader = open_reader(str(SAMPLE_LOG))
    assert reader.info.line is not None
    view = LiveView(LiveState("/dev/ttyUSB0", "19200 8E1", "site.mcap", "timing host"))
    statistics = analyze(reader, "live", Analysis(reader.info.line, TimingQuality.HOST), [view])
    reader.close()
    out = io.StringIO()
    Console(file=out, width=width, height=height, color_system=None).print(view.render(statistics))
    # The elapsed seconds change from run to run.
    return re.sub(r"^\d+ s, ", "N s, ", out.getvalue(), flags=re.MULTILINE)


@pytest.mark.parametrize(("width", "height"), SCREENS)
def test_live_screens_fill_the_terminal(width: int, height: int) -> None:
    screen = live_screen(width, height)
    lines = screen.splitlines()
    assert max(map(len, lines)) <= width
    # Fills the screen: a frame row more would not fit (rich keeps one line for the cursor).
    assert height - 4 <= len(lines) <= height - 1
    assert "lat ms" in screen and "~" in screen  # latency per frame, marked as read-time
    rows = [line for line in lines if re.match(r"^\s*\d+ \s*\d\d:\d\d:\d\d", line)]
    assert rows[-1].lstrip().startswith("51 ")  # the newest frame is last
    assert "error: Slave 3 never answered: 5 requests, no answer." in " ".join(screen.split())  # findings, live
    check_golden(f"live-{width}x{height}.txt", screen)


def midnight_capture(path: Path) -> Path:
    day = 1_700_006_399  # 2023-11-14 23:59:59 UTC
    lines = ["# rtu-capture v1", "# line: 19200 8E1", "# timing: exact",
             f"{day}.500000000 02 03 0C 1E 00 04 27 6C",
             f"{day + 1}.100000000 02 03 0C 1E 00 04 27 6C"]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_dates_appear_where_the_capture_crosses_midnight(cli: Cli, tmp_path: Path) -> None:
    capture = midnight_capture(tmp_path / "midnight.log")
    out = cli("analyze", str(capture)).out
    assert "# capture starts 2023-11-14 23:59:59 (UTC)" in out
    assert "# date 2023-11-15 (UTC)" in out
    assert out.index("23:59:59.49") < out.index("# date 2023-11-15") < out.index("00:00:00.09")


def test_time_modes(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    relative = cli("analyze", str(SAMPLE_LOG), "--time", "relative").out
    rows = [line.split() for line in relative.splitlines() if not line.startswith("#")]
    assert rows[0][1] == "0.000000" and rows[1][1] == "0.007305"  # from the first frame read
    assert "capture starts" not in relative
    monkeypatch.setenv("TZ", "America/New_York")
    time.tzset()
    try:
        local = cli("analyze", str(midnight_capture(tmp_path / "m.log")), "--time", "local").out
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    assert "# capture starts 2023-11-14 18:59:59 (local time)" in local and "# date" not in local
    assert "18:59:59.49" in local


def test_wrong_view_options_are_one_line(cli: Cli) -> None:
    with pytest.raises(SystemExit) as stopped:
        cli("analyze", str(SAMPLE_LOG), "--time", "mars")
    assert stopped.value.code == 2


@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")
@pytest.mark.parametrize(("width", "height"), SCREENS)
def test_real_terminal_in_tmux(tmp_path: Path, width: int, height: int) -> None:
    """The table in a real terminal (tmux): as wide as the pane, in colour, nothing past the edge."""
    session = f"rtusniff-{os.getpid()}-{width}"
    done = tmp_path / "done"
    # env -u: a COLUMNS inherited from the test run would override the pane's size.
    command = (f"env -u COLUMNS -u LINES {sys.executable} -m sniffer analyze {SAMPLE_LOG} --limit 8; "
               f"touch {done}; sleep 30")
    subprocess.run(["tmux", "-L", session, "new-session", "-d", "-x", str(width), "-y", str(height),
                    "-e", "TERM=xterm-256color", "-e", f"PYTHONPATH={ROOT}", command], check=True)
    try:
        deadline = time.monotonic() + 20
        while not done.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        screen = subprocess.run(["tmux", "-L", session, "capture-pane", "-p", "-e", "-S", "-"], check=True,
                                capture_output=True, text=True).stdout
    finally:
        subprocess.run(["tmux", "-L", session, "kill-server"], check=False)
    plain = re.sub(r"\x1b\[[0-9;]*m", "", screen)
    assert "\x1b[" in screen  # colours on a terminal
    assert "time (UTC)" in plain and "# 8 frames" not in plain and "8 frames, " in plain
    assert all(len(line) <= width for line in plain.splitlines())
    header = next(line for line in plain.splitlines() if "time (UTC)" in line)
    assert ("hex" in header) == (width >= 200)


def run_on_pty(argv: list[str], columns: int = 150) -> str:
    """Run rtusniff with standard error on a pseudo-terminal (standard output to nowhere); what
    the terminal got, without escape codes."""
    import pty
    import select

    master, slave = pty.openpty()
    process = subprocess.Popen([sys.executable, "-m", "sniffer", *argv], stderr=slave, stdout=subprocess.DEVNULL,
                               env={**os.environ, "COLUMNS": str(columns), "PYTHONPATH": str(ROOT)})
    os.close(slave)
    received = b""
    while True:
        ready, _, _ = select.select([master], [], [], 0.5)
        if ready:
            try:
                data = os.read(master, 65536)
            except OSError:  # the child closed the terminal
                break
            if not data:
                break
            received += data
        elif process.poll() is not None:
            break
    process.wait(timeout=60)
    os.close(master)
    assert process.returncode == 0, received
    return re.sub(r"\x1b\[[0-9;?]*[a-zA-Z]", "", received.decode(errors="replace"))


@pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals are POSIX")
def test_progress_bar_on_a_terminal(tmp_path: Path) -> None:
    from benchmarks.bench_memory import write_capture

    capture = tmp_path / "long.mcap"
    write_capture(capture, 60_000)
    shown = run_on_pty(["stats", str(capture), "-o", str(tmp_path / "stats.txt")])
    assert "long.mcap" in shown and " %" in shown and "frames/s" in shown and "MB" in shown
    assert f"wrote {tmp_path / 'stats.txt'}: table statistics of 60,000 frames" in shown
    copied = run_on_pty(["convert", str(capture), str(tmp_path / "long.log")])
    assert "chunks/s" in copied and "wrote" in copied
    quiet = run_on_pty(["export", str(capture), "--pcap", str(tmp_path / "long.pcap"), "-q"])
    assert quiet.strip() == ""
    reported = run_on_pty(["report", str(capture), "-o", str(tmp_path / "long.html")])
    assert "frames/s" in reported and f"wrote {tmp_path / 'long.html'}: html report of 60,000 frames" in reported


def test_no_bar_over_output_that_streams_to_the_terminal(tmp_path: Path) -> None:
    """A command writing to standard output as it goes shows no bar, even into a pipe: what reads
    the pipe (less, head) draws on the same terminal. A command that writes at the end shows one."""
    from benchmarks.bench_memory import write_capture

    capture = tmp_path / "long.mcap"
    write_capture(capture, 60_000)
    assert run_on_pty(["analyze", str(capture)]).strip() == ""
    assert run_on_pty(["values", str(capture)]).strip() == ""
    assert "frames/s" in run_on_pty(["stats", str(capture)])


@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")
def test_the_bar_is_gone_before_the_statistics_are_written(tmp_path: Path) -> None:
    """``stats CAPTURE | head``: the bar (standard error, the terminal) is erased before the table
    goes down the pipe to the same terminal; no bar is left with the table's first line after it."""
    from benchmarks.bench_memory import write_capture

    capture = tmp_path / "long.mcap"
    write_capture(capture, 200_000)
    session, done = f"rtusniff-bar-{os.getpid()}", tmp_path / "done"
    command = (f"env -u COLUMNS -u LINES {sys.executable} -m sniffer stats {capture} | head -3; "
               f"touch {done}; sleep 30")
    subprocess.run(["tmux", "-L", session, "new-session", "-d", "-x", "120", "-y", "30",
                    "-e", f"PYTHONPATH={ROOT}", command], check=True)
    try:
        deadline = time.monotonic() + 60
        while not done.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        screen = subprocess.run(["tmux", "-L", session, "capture-pane", "-p", "-S", "-"], check=True,
                                capture_output=True, text=True).stdout
    finally:
        subprocess.run(["tmux", "-L", session, "kill-server"], check=False)
    lines = [line for line in screen.splitlines() if line.strip()]
    assert lines[0] == f"# {capture}  line 115200 8N1  timing exact", screen
    assert "━" not in screen and "frames/s" not in screen


@pytest.mark.parametrize("columns", [80, 200])
def test_a_bar_keeps_its_times_whole_at_any_width(tmp_path: Path, columns: int) -> None:
    """At 80 columns the size read and the rate give way; the elapsed and remaining times, the
    share and the frames stay whole (not ``0… 0:0…``)."""
    from benchmarks.bench_memory import write_capture

    capture = tmp_path / "long.mcap"
    write_capture(capture, 200_000)
    shown = run_on_pty(["export", str(capture), "--mcap", str(tmp_path / "out.mcap"), "--jobs", "1"], columns)
    bars = [line for line in shown.splitlines() if "━" in line]
    assert bars, shown
    for bar in bars:
        # The first redraw has no frames yet; every one has both times whole.
        assert re.search(r"\d+ %( .*)? \d:\d\d:\d\d( -:--:--| \d:\d\d:\d\d)$", bar.strip()), bar
        assert len(bar.rstrip()) <= columns
    assert any(re.search(r"\d+ % (≈ [^ ]+ of [^ ]+ MB )?[\d,]+ frames ", bar) for bar in bars), bars
    assert ("frames/s" in shown) == (columns >= 120)


def test_a_bar_over_many_captures_on_a_terminal(tmp_path: Path) -> None:
    """``--each``: a bar over the captures (done of all, their megabytes) for stats, report and
    export; nothing of it with --quiet."""
    from benchmarks.bench_memory import write_capture

    folder = tmp_path / "site"
    folder.mkdir()
    for extra, name in enumerate(("a.mcap", "b.mcap", "c.mcap")):  # three captures: a dataset holds each once
        write_capture(folder / name, 30_000 + 100 * extra)
    for command in (["stats", "--each", str(folder), "-o", str(tmp_path / "s.txt")],
                    ["report", "--each", str(folder), "-o", str(tmp_path / "r.html")],
                    ["export", "--each", str(folder), "--parquet", str(tmp_path / "d")]):
        shown = run_on_pty([*command, "--jobs", "1"])
        assert "of 3 captures" in shown and " MB" in shown and " %" in shown, (command, shown)
    assert run_on_pty(["stats", "--each", str(folder), "-o", str(tmp_path / "q.txt"), "-q"]).strip() == ""


def test_live_screen_is_a_snapshot() -> None:
    """rich redraws in its own thread while the capture thread goes on adding frames: a screen
    shows what there was when it was made, and never iterates what is being changed."""
    reader = open_reader(str(SAMPLE_LOG))
    assert reader.info.line is not None
    view = LiveView(LiveState("/dev/ttyUSB0", "19200 8E1", None, "timing host"))
    statistics = analyze(reader, "live", Analysis(reader.info.line, TimingQuality.HOST), [view])
    reader.close()
    screen = view.render(statistics)
    recent = list(view._recent)
    for _ in range(40):  # what the capture thread does meanwhile: the deque turns over
        for batch, _latencies in recent:
            view.messages(batch)
    statistics.per_function.clear()
    out = io.StringIO()
    Console(file=out, width=120, height=40, color_system=None).print(screen)
    # The counters of when it was made (the statistics were cleared since), the frames of then.
    assert re.search(r"^\s+20\s+7\s+7\s", out.getvalue(), re.MULTILINE), out.getvalue()
    assert out.getvalue().rstrip().splitlines()[-1].split()[0] == "51"


@pytest.mark.skipif(not hasattr(os, "fork"), reason="--jobs 2 forks")
@pytest.mark.parametrize("options", [[], ["--hex"], ["--filter", "role=response", "--filter", "slave=2"],
                                     ["--from", "1s", "--limit", "9"], ["--around", "26", "--context", "3"],
                                     ["--time", "relative", "--filter", "crc=bad"]])
def test_plain_table_is_the_same_in_one_process_and_two(cli: Cli, options: list[str]) -> None:
    """The plain table is laid out where frames are paired (the decoding process with --jobs 2)
    and finished with the summaries here: the same lines either way."""
    for capture in (SAMPLE_LOG, ROOT / "captures" / "atv71-plc-poll-usb.mcap"):
        one = cli("analyze", str(capture), "--jobs", "1", *options)
        two = cli("analyze", str(capture), "--jobs", "2", *options)
        assert one.code == two.code == 0, one.err + two.err
        assert one.out == two.out


@pytest.mark.parametrize("mode", ["utc", "relative", "local"])
def test_plain_rows_by_numpy_are_the_plain_path(tmp_path: Path, mode: str) -> None:
    """The plain table's fields laid out by numpy (sniffer/views/fixed_width.py) are what the
    row-by-row path writes, on every sample and on generated traffic of every kind."""
    from benchmarks import generate_capture
    from benchmarks.bench_framing import LINE

    captures = sorted((ROOT / "captures").glob("*.mcap"))
    for values in ("random", "steady"):
        generated = tmp_path / f"{values}.mcap"
        generate_capture.write(generated, 6000, 3, LINE, "exact", values=values)
        captures.append(generated)
    for capture in captures:
        outputs = []
        for fast in (True, False):
            reader = open_reader(str(capture))
            assert reader.info.line is not None
            out = io.StringIO()
            view = PlainTableView(out, clock=Clock(mode), fast=fast)
            analyze(reader, capture.name, Analysis(reader.info.line, reader.info.timing), [view])
            reader.close()
            outputs.append(out.getvalue())
        assert outputs[0] == outputs[1], capture.name
        assert outputs[0].count("\n") > 10


def test_relative_times_count_from_the_first_frame_read(cli: Cli) -> None:
    """A filter does not move relative times, on a terminal or down a pipe; a window starts them."""
    for width in ("0", "120"):
        out = cli("analyze", str(SAMPLE_LOG), "--time", "relative", "--filter", "role=exception", "--width", width).out
        assert "1.441608" in out and "2.550759" in out
    windowed = cli("analyze", str(SAMPLE_LOG), "--time", "relative", "--around", "31", "--context", "1").out
    assert next(line.split()[1] for line in windowed.splitlines() if not line.startswith("#")) == "0.000000"


@pytest.mark.parametrize("width", range(12, 101))
def test_a_note_breaks_between_fields(width: int) -> None:
    """The line above the table breaks between its fields, so that no label ends a line without
    its value (``t3.5`` / ``2005 µs`` at 80 columns); a field wider than the line breaks between
    its words, a word wider than the line within itself: no line is ever wider than the terminal."""
    fields = ["captures/atv71-plc-poll.log", "line 19200 8E1", "timing exact", "t1.5 859 µs", "t3.5 2005 µs"]
    lines = note_lines("  ".join(fields), width)
    assert all(len(line) <= width for line in lines)
    assert "".join("".join(lines).split()) == "".join("".join(fields).split())  # every character, in order
    for field in fields:
        if len(field) <= width:
            assert any(field in line for line in lines), (width, field, lines)
