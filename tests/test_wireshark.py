"""Wireshark with rtusniff, as a user sets it up: ``rtusniff wireshark setup`` in a home of its
own, then tshark (Wireshark's own dissectors) on every shipped sample and real recording, and
live through the extcap on a pseudo-terminal fed by a pymodbus master and slave."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.real_recordings import RECORDINGS, TEXT, available

TSHARK = shutil.which("tshark")
CAPTURES = Path(__file__).resolve().parents[1] / "captures"
SAMPLES = sorted(CAPTURES.glob("*.log"))
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark (Wireshark) is not installed")


def rtusniff(home: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """The command as a user runs it, with ``home`` as their home (Wireshark's folders in it)."""
    env = {**os.environ, "HOME": str(home), "XDG_CONFIG_HOME": str(home / ".config")}
    return subprocess.run([sys.executable, "-m", "sniffer", *args], capture_output=True, text=True, env=env,
                          timeout=120, check=False)


def tshark(home: Path, *args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """tshark with the profile (``-G`` reports take no other option)."""
    assert TSHARK is not None
    env = {**os.environ, "HOME": str(home), "XDG_CONFIG_HOME": str(home / ".config")}
    options = [] if args[0] == "-G" else ["-n", "-C", "rtusniff"]
    return subprocess.run([TSHARK, *options, *args], capture_output=True, text=True, env=env, timeout=timeout,
                          check=False)


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A home where ``rtusniff wireshark setup`` ran."""
    folder = tmp_path_factory.mktemp("home")
    done = rtusniff(folder, "wireshark", "setup")
    assert done.returncode == 0, done.stderr
    return folder


def test_setup_writes_the_profile_and_the_launcher_and_nothing_else(tmp_path: Path) -> None:
    config, extcap = tmp_path / "config", tmp_path / "extcap"
    first = rtusniff(tmp_path, "wireshark", "setup", "--config-dir", str(config), "--extcap-dir", str(extcap),
                     "--port", "/dev/ttyAMA0")
    assert first.returncode == 0, first.stderr
    written = sorted(path.relative_to(tmp_path).as_posix() for path in tmp_path.rglob("*") if path.is_file())
    launcher = "rtusniff-extcap.bat" if sys.platform == "win32" else "rtusniff-extcap"
    assert written == ["config/profiles/rtusniff/preferences", "config/profiles/rtusniff/user_dlts",
                       f"extcap/{launcher}"]
    assert first.stdout.count("written") == 3 and "wireshark -C rtusniff" in first.stdout
    preferences = (config / "profiles" / "rtusniff" / "preferences").read_text()
    assert "mbrtu.udp.port: 502" in preferences and "mbrtu.crc_verification: TRUE" in preferences
    script = (extcap / launcher).read_text()
    assert sys.executable in script and "--port /dev/ttyAMA0" in script
    if sys.platform != "win32":
        assert os.access(extcap / launcher, os.X_OK)
    again = rtusniff(tmp_path, "wireshark", "setup", "--config-dir", str(config), "--extcap-dir", str(extcap),
                     "--port", "/dev/ttyAMA0")
    assert again.returncode == 0 and again.stdout.count("unchanged") == 3


@pytest.mark.parametrize("mine", ["profiles/rtusniff/preferences", "profiles/rtusniff/user_dlts"])
def test_setup_never_replaces_a_file_of_the_user(tmp_path: Path, mine: str) -> None:
    """A profile of the same name that the user made is theirs: refused before anything is written."""
    config, extcap = tmp_path / "config", tmp_path / "extcap"
    (config / mine).parent.mkdir(parents=True)
    (config / mine).write_text("gui.column.format: mine\n")
    refused = rtusniff(tmp_path, "wireshark", "setup", "--config-dir", str(config), "--extcap-dir", str(extcap))
    assert refused.returncode == 11 and refused.stderr.count("\n") == 1, refused.stderr
    assert str(config / mine) in refused.stderr and "not written by rtusniff" in refused.stderr
    assert (config / mine).read_text() == "gui.column.format: mine\n"
    assert [path.name for path in tmp_path.rglob("*") if path.is_file()] == [Path(mine).name]


@needs_tshark
def test_setup_finds_wireshark_s_own_folders(home: Path) -> None:
    """Where tshark says its personal configuration is (``-G folders``), the profile is there,
    and tshark lists the extcap's interfaces."""
    folders = tshark(home, "-G", "folders").stdout
    configuration = next(line.split(":", 1)[1].strip() for line in folders.splitlines()
                         if line.startswith("Personal configuration"))
    assert (Path(configuration) / "profiles" / "rtusniff" / "preferences").is_file()
    listed = tshark(home, "-D").stdout
    assert "(Modbus RTU (rtusniff): " in listed or "no serial ports" in listed


def classified(home: Path, pcap: Path) -> list[list[str]]:
    shown = tshark(home, "-r", str(pcap), "-T", "fields", "-E", "separator=;", "-e", "mbrtu.unit_id",
                   "-e", "mbrtu.crc16.status", "-e", "_ws.col.Info")
    assert shown.returncode == 0, shown.stderr
    return [row.split(";", 2) for row in shown.stdout.splitlines()]


def captures() -> list[Path]:
    real = [TEXT / name for name in RECORDINGS] if available() else []
    return [*SAMPLES, *real]


@needs_tshark
@pytest.mark.parametrize("capture", captures(), ids=lambda path: path.name)
def test_wireshark_classifies_every_frame_of_an_export(home: Path, tmp_path: Path, capture: Path,
                                                       cli: Callable[..., Any]) -> None:
    """``export --pcap`` as it is, opened with the profile: every Modbus frame a query or a
    response (none "Unable to classify"), the CRC verdicts rtusniff gives."""
    pcap = tmp_path / "out.pcapng"
    assert cli("export", str(capture), "--pcap", str(pcap), "-q").code == 0
    frames = [r for r in cli("analyze", str(capture), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    rows = classified(home, pcap)
    assert len(rows) == len(frames) > 0
    assert not [row for row in rows if "Unable to classify" in row[2]]
    for (unit, crc, info), frame in zip(rows, frames, strict=True):
        if frame["role"] == "noise" or frame["protocol"] != "modbus":
            assert unit == "", (frame["index"], info)  # UDP data, not Modbus: shown, never dissected
            continue
        assert int(unit) == frame["slave"] and crc == ("1" if frame["crc_ok"] else "0"), (frame["index"], info)
        assert info.lstrip().startswith("Query" if frame["role"] in ("request", "broadcast") else "Response")


def test_extcap_answers_wireshark_s_questions(tmp_path: Path) -> None:
    """The sentences of Wireshark's extcap grammar: interfaces (the ports named at setup among
    them), the link type, the options dialog."""
    listed = rtusniff(tmp_path, "wireshark", "extcap", "--extcap-interfaces", "--extcap-version=4.0",
                      "--port", "/dev/ttyAMA0")
    assert listed.returncode == 0 and listed.stderr == ""
    lines = listed.stdout.splitlines()
    assert lines[0].startswith("extcap {version=") and \
        "interface {value=rtusniff:/dev/ttyAMA0}{display=Modbus RTU (rtusniff): /dev/ttyAMA0}" in lines
    dlts = rtusniff(tmp_path, "wireshark", "extcap", "--extcap-interface", "rtusniff:/dev/ttyAMA0", "--extcap-dlts")
    assert dlts.stdout.startswith("dlt {number=101}")
    config = rtusniff(tmp_path, "wireshark", "extcap", "--extcap-interface=rtusniff:/dev/ttyAMA0",
                      "--extcap-config").stdout.splitlines()
    calls = [line.split("{call=")[1].split("}")[0] for line in config]
    assert calls == ["--line", "--char-timing", "--response-timeout", "--record", "--profile"]
    assert all(line.startswith("arg {number=") and line.count("{") == line.count("}") for line in config)


@pytest.mark.parametrize(("args", "said"), [
    (["--extcap-interface", "eth0", "--extcap-config"], "is not one of rtusniff's"),
    (["--extcap-interface", "rtusniff:/dev/x", "--capture"], "--capture needs --fifo"),
    (["--extcap-interface", "rtusniff:/dev/x", "--capture", "--fifo", "f", "--extcap-capture-filter", "port 1"],
     "capture filters are not supported"),
    (["--extcap-interface", "rtusniff:/dev/x", "--capture", "--fifo", "f", "--line", "19200 8Q1"], "--line"),
    ([], "give --extcap-interfaces"),
    (["--extcap-interface", "rtusniff:/dev/x", "--capture", "--fifo", "f", "--profile", "2=nosuch"],
     "unknown profile 'nosuch'"),
])
def test_extcap_refuses_what_it_cannot_do_in_one_line(tmp_path: Path, args: list[str], said: str) -> None:
    result = rtusniff(tmp_path, "wireshark", "extcap", *args)
    assert result.returncode == 2 and said in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert not (tmp_path / "f").exists()


@needs_tshark
@pytest.mark.skipif(sys.platform == "win32" or shutil.which("socat") is None, reason="needs socat pseudo-terminals")
@pytest.mark.parametrize("route", ["extcap", "pipe"])
def test_wireshark_captures_live(tmp_path: Path, route: str) -> None:
    """tshark on a tap of a line where a pymodbus master polls a pymodbus slave, through the extcap
    interface (its options set as tshark sets them) or through ``capture --pcap -`` piped into
    it: every frame, as a query or a response, with no byte lost (the recording holds every byte
    the line carried), and the capture stopped by tshark cleanly."""
    import re
    import tempfile

    from tests.ptylab import Relay, pty_pair, pymodbus_slave
    from tests.test_pty_pymodbus import run_master

    short = Path(tempfile.mkdtemp(prefix="rtx", dir="/tmp"))  # a port name Wireshark's settings keep as it is
    env = {**os.environ, "HOME": str(tmp_path), "XDG_CONFIG_HOME": str(tmp_path / ".config")}
    recording, pcap = tmp_path / "line.log", tmp_path / "live.pcapng"
    assert TSHARK is not None
    try:
        with pty_pair(short, "m") as master, pty_pair(short, "s") as slave, pty_pair(short, "t") as tap:
            assert rtusniff(tmp_path, "wireshark", "setup", "--port", str(tap.b)).returncode == 0
            interface = f"rtusniff:{tap.b}"
            key = re.sub(r"[^a-z0-9]", "_", interface.lower())
            capture = None
            if route == "extcap":
                wireshark = subprocess.Popen(
                    [TSHARK, "-C", "rtusniff", "-i", interface, "-o", f"extcap.{key}.line:19200 8N1",
                     "-o", f"extcap.{key}.record:{recording}", "-o", f"extcap.{key}.profile:1=generic",
                     "-a", "duration:12", "-w", str(pcap)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                    text=True)
            else:
                capture = subprocess.Popen(
                    [sys.executable, "-m", "sniffer", "capture", str(tap.b), "--line", "19200 8N1", "-o",
                     str(recording), "--pcap", "-", "--duration", "8"], env=env, stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE)
                wireshark = subprocess.Popen([TSHARK, "-C", "rtusniff", "-i", "-", "-w", str(pcap)], env=env,
                                             stdin=capture.stdout, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                             text=True)
            deadline = time.monotonic() + 10
            while not recording.exists() and time.monotonic() < deadline:
                time.sleep(0.05)  # the port is open
            assert recording.exists(), wireshark.communicate(timeout=30)
            with pymodbus_slave(slave.b), Relay(master.b, slave.a, copy_to=tap.a) as relay:
                operations = run_master(master.a)
                time.sleep(0.3)
            _, err = wireshark.communicate(timeout=60)
            assert wireshark.returncode == 0, err
            if capture is not None:
                assert capture.wait(timeout=30) == 0
    finally:
        shutil.rmtree(short, ignore_errors=True)
    on_the_line = b"".join(data for _, data in relay.tap)
    assert len(operations) >= 10 and len(on_the_line) > 200
    import contextlib
    import io
    import json

    from sniffer.cli import main  # the recording, whole: every byte of the line, read back

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["analyze", str(recording), "--format", "jsonl"]) == 0
    frames = [r for r in map(json.loads, out.getvalue().splitlines()) if r["kind"] == "frame"]
    assert bytes.fromhex("".join(frame["hex"] for frame in frames)) == on_the_line
    rows = classified(tmp_path, pcap)
    assert len(rows) == len(frames) >= 2 * len(operations) - 2
    assert not [row for row in rows if "Unable to classify" in row[2] or row[0] == ""]
    if route == "extcap":  # pcapng, with rtusniff's comments (a classic pcap through the pipe has none)
        comments = tshark(tmp_path, "-r", str(pcap), "-T", "fields", "-e", "frame.comment").stdout.splitlines()
        assert comments[0] == "rtusniff #0: request — read coils 10..21 (12)"
        assert comments[1].startswith("rtusniff #1: response to #0 — coils = ")


@needs_tshark
def test_each_packet_s_comment_says_what_rtusniff_found(home: Path, tmp_path: Path, cli: Callable[..., Any]) -> None:
    """The comment Wireshark shows under each packet: the frame's number, role, pairing and
    latency, flags, then its summary as ``analyze`` writes it, the values a profile names
    included (what Wireshark does not know of a drive)."""
    capture = CAPTURES / "atv71-plc-poll.log"
    pcap = tmp_path / "poll.pcapng"
    assert cli("export", str(capture), "--pcap", str(pcap), "--profile", "atv71", "-q").code == 0
    frames = [r for r in cli("analyze", str(capture), "--format", "jsonl", "--profile", "atv71").jsonl()
              if r["kind"] == "frame"]
    comments = tshark(home, "-r", str(pcap), "-T", "fields", "-e", "frame.comment").stdout.splitlines()
    assert len(comments) == len(frames)
    for comment, frame in zip(comments, frames, strict=True):
        said, summary = comment.split(" — ", 1)
        assert said.startswith(f"rtusniff #{frame['index']}: {frame['role']}") and summary == frame["summary"]
        assert all(flag in said for flag in frame["flags"])
    assert any("tFr = 60.0 Hz" in comment for comment in comments)


@pytest.mark.parametrize(("args", "code", "said"), [
    (["--pcap", "-", "--format", "jsonl"], 2, "--format jsonl cannot share it"),
    (["--pcap", "out.pcapng", "--quiet", "-o", "rec.log"], 2, "--quiet records only"),
    (["--pcap", "rec.log", "-o", "rec.log"], 2, "named as two outputs"),
    (["--pcap", "old.pcapng"], 11, "exists"),
])
def test_capture_pcap_options_refused_before_the_port_opens(tmp_path: Path, args: list[str], code: int,
                                                            said: str) -> None:
    (tmp_path / "old.pcapng").write_bytes(b"keep")
    result = subprocess.run([sys.executable, "-m", "sniffer", "capture", str(tmp_path / "no-such-port"), "--line",
                             "19200 8E1", *args], capture_output=True, text=True, cwd=tmp_path, timeout=60,
                            check=False, stdin=subprocess.DEVNULL)
    assert result.returncode == code and said in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert sorted(path.name for path in tmp_path.iterdir()) == ["old.pcapng"]
    assert (tmp_path / "old.pcapng").read_bytes() == b"keep"


@pytest.mark.skipif(sys.platform == "win32", reason="a FIFO is POSIX")
def test_a_pipe_whose_reader_left_ends_the_pcap_without_an_error(tmp_path: Path) -> None:
    """Wireshark stops a capture by closing the FIFO: the next write finds no reader, and the
    pcap sink says so (a live capture then ends as at Ctrl-C) instead of failing."""
    import threading

    from decoders.capture import Chunk, ChunkBatch, TimingQuality
    from decoders.line import LineSettings
    from decoders.pipeline import Decoder
    from sniffer.exports.outputs import PcapSink
    from tests.test_findings import T0, answer, read

    fifo = tmp_path / "wireshark.fifo"
    os.mkfifo(fifo)
    opened = threading.Event()

    def wireshark() -> None:  # opens the FIFO and goes away
        with open(fifo, "rb"):
            opened.set()

    reader = threading.Thread(target=wireshark)
    reader.start()
    sink = PcapSink(str(fifo), pcapng=False)  # opening waits for the reader
    reader.join(timeout=10)
    assert opened.is_set() and not reader.is_alive()
    decoder = Decoder(LineSettings.parse("19200 8E1"), TimingQuality.EXACT)
    chunks = ChunkBatch.from_chunks([Chunk(T0, read(1)), Chunk(T0 + 10_000_000, answer(1))])
    for batch in [*decoder.feed(chunks), *decoder.flush()]:
        sink.frames(batch)  # no reader: no error, the sink knows
    assert sink.reader_gone and sink.exporter is None
    sink.close()
