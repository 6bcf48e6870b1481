"""``rtusniff capture`` on pseudo-terminals: a real master and slave, signals, crashes, a vanishing port."""

from __future__ import annotations

import json
import os
import re
import resource
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import pytest
import serial

from decoders.line import LineSettings
from sniffer.serial_source import SerialSource
from tests.ptylab import SOCAT, Relay, pty_pair, pymodbus_slave

pytestmark = pytest.mark.skipif(SOCAT is None, reason="needs socat (apt-get install socat; .ci/run installs it)")
REQUEST = bytes.fromhex("02030C1E0004276C")
RESPONSE = bytes.fromhex("0203080028025801F4000052B0")


#: How long a capture may take to stop after its signal before the test calls it hung: generous,
#: because a loaded CI machine (its disk busy, fsync slow) can take seconds to close a recording.
HANG_S = 60


def start_capture(port: Path, *args: str, ignore_sigint: bool = True, **kwargs: Any) -> subprocess.Popen[str]:
    """A capture in a child process, returned once it says it is capturing (its first line on
    standard error). Started with SIGINT ignored, as a shell starts a background job: the
    capture must install its own handlers for Ctrl-C and SIGTERM to work."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN if ignore_sigint else signal.default_int_handler)
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", "sniffer", "capture", str(port), "--line", "19200", "8N1", *args],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs,
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    wait_until_capturing(process)
    return process


def wait_until_capturing(process: subprocess.Popen[str], timeout_s: float = HANG_S) -> None:
    assert process.stderr is not None
    deadline, said = time.monotonic() + timeout_s, []
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stderr], [], [], 0.1)
        if ready:
            line = process.stderr.readline()
            said.append(line)
            if line.startswith("capturing "):
                return
            if not line and process.poll() is not None:
                break
    process.kill()
    raise AssertionError(f"capture never said it was capturing: {''.join(said)!r}")


def analyze(path: Path) -> tuple[int, list[dict[str, Any]], str]:
    result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", str(path), "--format", "jsonl"],
                            capture_output=True, text=True, check=False)
    return result.returncode, [json.loads(line) for line in result.stdout.splitlines()], result.stderr


def frames_of(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in records if r["kind"] == "frame"]


@pytest.fixture
def line_tap(tmp_path: Path) -> Iterator[tuple[Path, Path, subprocess.Popen[bytes]]]:
    """A pty pair: write frames at ``a`` as the line; capture reads ``b``."""
    with pty_pair(tmp_path, "line") as pair:
        yield pair.a, pair.b, pair.process


def send_exchanges(port: Path, count: int, pause_s: float = 0.05, stop: Any = None) -> None:
    with serial.Serial(str(port), 19200, timeout=0) as line:
        for _ in range(count):
            if stop is not None and stop.is_set():
                return
            line.write(REQUEST)
            time.sleep(0.004)
            line.write(RESPONSE)
            time.sleep(pause_s)


def test_real_master_and_slave_decoded_live_and_recorded(tmp_path: Path) -> None:
    from tests.test_pty_pymodbus import assert_session_decoded, run_master

    # A directory name longer than a line, with brackets: the closing message must name the
    # file as it is, on one line (stderr to a pipe is 80 columns to rich, which wrapped it
    # mid-path; and rich markup took "[site-a]" for a style and dropped it).
    recording = tmp_path / ("[site-a]-recordings-directory-named-longer-than-one-terminal-line-" * 2) / "live.mcap"
    recording.parent.mkdir()
    with pty_pair(tmp_path, "master") as to_master, pty_pair(tmp_path, "slave") as to_slave, \
            pty_pair(tmp_path, "tap") as tap:
        capture = start_capture(tap.b, "-o", str(recording), "--format", "jsonl")
        with pymodbus_slave(to_slave.b), Relay(to_master.b, to_slave.a, absent=frozenset({9}),
                                               copy_to=tap.a) as relay:
            operations = run_master(to_master.a)
            time.sleep(1.5)
            capture.send_signal(signal.SIGINT)
            out, err = capture.communicate(timeout=HANG_S)
            assert relay.written_back() == b""  # passive: nothing came back from the capture's port
    assert capture.returncode == 130, err
    said = err.splitlines()
    assert any(line.startswith("recorded ") and line.endswith(f" bytes to {recording}") for line in said), err
    live = [json.loads(line) for line in out.splitlines()]
    code, recorded, warnings = analyze(recording)
    assert code == 0 and not warnings
    for records in (live, recorded):
        assert_session_decoded(operations, records)
    assert live[-1]["kind"] == "summary"
    # Live and offline agree on every frame's verdict (issue 66: live gave timeout + unexpected +
    # retry triples where analyze gave none; tests/property/test_live_offline.py holds the rule).
    verdicts = [[(r["index"], r["role"], r["request_index"], r["flags"]) for r in records if r["kind"] == "frame"]
                for records in (live, recorded)]
    assert verdicts[0] == verdicts[1]


def test_passive_open_keeps_rts_and_dtr_off(line_tap: tuple[Path, Path, Any]) -> None:
    _, port, _ = line_tap
    source = SerialSource(str(port), LineSettings.parse("19200 8N1"))
    status = source.open()
    try:
        assert (source.rts, source.dtr) == (False, False)
        # A pseudo-terminal has no modem lines: the driver cannot report them back, and says so.
        assert status.modem_lines is None and "cannot report them back" in status.modem_note()
    finally:
        source.close()


def test_rts_is_cleared_even_when_clearing_dtr_fails() -> None:
    """pyserial clears both in one step at open, and skips RTS when DTR fails (on a pty): each is
    cleared again on its own."""

    class Port:
        cleared: ClassVar[list[str]] = []

        @property
        def dtr(self) -> bool:
            return True

        @dtr.setter
        def dtr(self, value: bool) -> None:
            raise OSError(25, "Inappropriate ioctl for device")

        @property
        def rts(self) -> bool:
            return True

        @rts.setter
        def rts(self, value: bool) -> None:
            self.cleared.append(f"rts={value}")

    source = SerialSource("/dev/null", LineSettings.parse("19200 8N1"))
    source._serial = Port()  # type: ignore[assignment]
    source._clear_modem_lines()
    assert Port.cleared == ["rts=False"]


def test_what_the_recording_says_of_rts_and_dtr() -> None:
    from sniffer.serial_source import PortStatus

    assert PortStatus(None, None, False, {"RTS": False, "DTR": False}).modem_note() == \
        "RTS/DTR: both off, as the driver reports them"
    assert "RTS still on after clearing" in PortStatus(None, None, False, {"RTS": True, "DTR": False}).modem_note()


@pytest.mark.parametrize(("stop", "exit_code", "name"), [(signal.SIGTERM, 143, "term.log"),
                                                         (signal.SIGINT, 130, "int.mcap")])
def test_a_stop_signal_closes_the_recording(tmp_path: Path, line_tap: tuple[Path, Path, Any],
                                            stop: signal.Signals, exit_code: int, name: str) -> None:
    """SIGTERM, and SIGINT although the capture was started with SIGINT ignored (as a script's
    shell starts `rtusniff capture … &`): both stop it cleanly with every byte recorded."""
    line, port, _ = line_tap
    recording = tmp_path / name
    capture = start_capture(port, "-o", str(recording), "--quiet", ignore_sigint=True)
    send_exchanges(line, 10)
    time.sleep(0.5)
    capture.send_signal(stop)
    _, err = capture.communicate(timeout=HANG_S)
    assert capture.returncode == exit_code, err
    code, records, _ = analyze(recording)
    assert code == 0
    assert len([f for f in frames_of(records) if f["crc_ok"]]) == 20


@pytest.mark.skipif(os.name != "posix", reason="the lock is POSIX's flock; Windows opens a port for one program")
def test_a_second_capture_on_one_port_is_refused(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    """Two captures on one port would split its bytes between them: the second is refused with
    one line, and the first records every byte."""
    line, port, _ = line_tap
    first = start_capture(port, "-o", str(tmp_path / "first.mcap"), "--quiet")
    second = subprocess.run([sys.executable, "-m", "sniffer", "capture", str(port), "--line", "19200", "8N1", "-o",
                             str(tmp_path / "second.mcap")], capture_output=True, text=True, check=False, timeout=60)
    assert second.returncode == 4, second.stderr
    assert second.stderr.count("\n") == 1 and "the port is in use" in second.stderr
    assert not (tmp_path / "second.mcap").exists()
    send_exchanges(line, 10)
    time.sleep(0.5)
    first.send_signal(signal.SIGTERM)
    first.communicate(timeout=HANG_S)
    code, records, _ = analyze(tmp_path / "first.mcap")
    assert code == 0 and len([f for f in frames_of(records) if f["crc_ok"]]) == 20


def test_kill_9_keeps_everything_before_the_last_flush(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    line, port, _ = line_tap
    recording = tmp_path / "crash.mcap"
    capture = start_capture(port, "-o", str(recording), "--quiet")
    send_exchanges(line, 10)
    time.sleep(2.5)  # at least two flushes after the last byte
    capture.kill()
    capture.wait(timeout=10)
    code, records, warnings = analyze(recording)
    assert code == 0, warnings
    assert "recording cut short" in warnings
    assert len([f for f in frames_of(records) if f["crc_ok"]]) == 20


def test_port_vanishing_ends_the_capture_cleanly(tmp_path: Path) -> None:
    recording = tmp_path / "gone.mcap"
    with pty_pair(tmp_path, "usb") as pair:
        capture = start_capture(pair.b, "-o", str(recording), "--quiet")
        send_exchanges(pair.a, 5)
        time.sleep(0.5)
        pair.process.kill()  # the adapter is unplugged
        _, err = capture.communicate(timeout=HANG_S)
    assert capture.returncode == 13, err
    assert "the port went away" in err and err.count("error:") == 1 and "Traceback" not in err
    code, records, warnings = analyze(recording)
    assert code == 0 and not warnings  # closed properly
    assert len([f for f in frames_of(records) if f["crc_ok"]]) == 10


def test_full_disk_keeps_a_readable_recording(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    line, port, _ = line_tap
    recording = tmp_path / "full.mcap"

    def small_disk() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (3000, 3000))

    capture = start_capture(port, "-o", str(recording), "--quiet", "--duration", "20", preexec_fn=small_disk)
    send_exchanges(line, 5)
    time.sleep(1.5)  # a flush with valid frames in it
    with serial.Serial(str(line), 19200, timeout=0) as writer:
        for _ in range(30):
            writer.write(os.urandom(200))  # bytes that do not compress: the "disk" fills up
            time.sleep(0.1)
    _, err = capture.communicate(timeout=30)
    assert capture.returncode == 11, err
    assert "writing failed" in err and "kept up to its last flush" in err
    code, records, warnings = analyze(recording)
    assert code == 0 and "recording cut short" in warnings
    assert len([f for f in frames_of(records) if f["crc_ok"]]) >= 10
    assert recording.stat().st_size <= 3000


def test_rotation_by_duration(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    line, port, _ = line_tap
    capture = start_capture(port, "-o", str(tmp_path / "rot.log"), "--quiet", "--rotate", "1s")
    for _ in range(4):
        send_exchanges(line, 5)
        time.sleep(0.6)
    capture.send_signal(signal.SIGINT)
    _, err = capture.communicate(timeout=HANG_S)
    files = sorted(tmp_path.glob("rot-*.log"))
    assert len(files) >= 2, err
    total = 0
    for path in files:
        code, records, err = analyze(path)
        frame_bytes = sum(len(f["hex"]) // 2 for f in frames_of(records))
        # A second in which the line was quiet is a valid, empty segment: exit 14 says so.
        assert (code, frame_bytes > 0) in {(0, True), (14, False)}, err
        total += frame_bytes
    assert total == 20 * (len(REQUEST) + len(RESPONSE))


def test_line_auto_finds_the_settings(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    line, port, _ = line_tap
    import threading

    stop = threading.Event()
    sender = threading.Thread(target=send_exchanges, args=(line, 400, 0.02, stop), daemon=True)
    sender.start()
    try:
        result = subprocess.run(
            [sys.executable, "-m", "sniffer", "capture", str(port), "--line", "auto", "--probe-seconds", "0.4",
             "--duration", "1", "-o", str(tmp_path / "auto.log"), "--quiet"],
            capture_output=True, text=True, check=False, timeout=60,
        )
    finally:
        stop.set()
        sender.join(timeout=5)
    assert result.returncode == 0, result.stderr
    # Pseudo-terminals ignore baud rate and parity: every setting hears valid frames, and the
    # most common one wins the tie, which is never called sure.
    assert "line 19200 8E1 chosen (not sure: 9600 8E1, 19200 8N1, 9600 8N1, … read as well; the commoner " \
           "setting is taken): 100% of" in result.stderr, result.stderr
    code, records, _ = analyze(tmp_path / "auto.log")
    assert code == 0 and frames_of(records)


def test_capture_refuses_to_overwrite(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    _, port, _ = line_tap
    existing = tmp_path / "old.mcap"
    existing.write_bytes(b"precious")
    result = subprocess.run([sys.executable, "-m", "sniffer", "capture", str(port), "--line", "19200", "8N1",
                             "-o", str(existing)], capture_output=True, text=True, check=False)
    assert result.returncode == 11 and "never overwrites" in result.stderr
    assert existing.read_bytes() == b"precious"
    missing = subprocess.run([sys.executable, "-m", "sniffer", "capture", "/dev/ttyNOPE", "--line", "19200", "8N1"],
                             capture_output=True, text=True, check=False)
    assert missing.returncode == 4 and "cannot open the port" in missing.stderr
    assert os.path.exists(port)


def test_live_view_shows_slaves_and_frames(tmp_path: Path, line_tap: tuple[Path, Path, Any]) -> None:
    line, port, _ = line_tap
    capture = start_capture(port, "--duration", "3", "--profile", "atv71", env={**os.environ, "COLUMNS": "160"})
    send_exchanges(line, 10)
    out, err = capture.communicate(timeout=20)
    assert capture.returncode == 0, err
    assert "requests" in out and "lat p50 ms" in out and "lat ms" in out  # slaves, then frames
    # The value with its unit; the summary may wrap between them, the hex column beside it (the
    # columns' widths follow the times read, which a loaded machine stretches).
    words = out.split()
    at = next(place for place in range(len(words)) if words[place : place + 3] == ["SFr", "=", "4.0"])
    assert "kHz," in words[at + 3 : at + 24]
    assert "timing host" in out
    # Host timing measures no latency on the wire: the slaves' p50 and p95 are those between read
    # times, marked "~" as the frames' are (they stayed empty while the frames showed "~0.6").
    header = next(line for line in out.splitlines() if "lat p50 ms" in line)
    row = out.splitlines()[out.splitlines().index(header) + 1]
    assert re.search(r"~\d+\.\d\s+~\d+\.\d", row), (header, row)


def test_rotation_and_port_listing_options(cli: Any, tmp_path: Path) -> None:
    from sniffer.io.rotation import rotated_path
    from sniffer.recorder import Rotation

    assert Rotation.parse("100MB") == Rotation(max_bytes=100_000_000)
    assert Rotation.parse("1.5h") == Rotation(max_seconds=5400.0)
    assert rotated_path("/x/cap.mcap", 3) == "/x/cap-0003.mcap"
    bad = cli("capture", "/dev/null", "--line", "19200", "8N1", "-o", str(tmp_path / "x.mcap"), "--rotate", "soon")
    assert bad.code == 2 and "give a size (100MB, 1GB) or a duration" in bad.err
    listed = cli("ports")
    assert listed.code == 0


def test_latency_timer_advice() -> None:
    from sniffer.serial_source import PortStatus

    assert PortStatus(True, 16, False).advice() is not None
    assert "latency timer is 16 ms" in (PortStatus(True, 16, False).advice() or "")
    assert PortStatus(True, 1, False).advice() is None
    assert PortStatus(None, None, False).advice() is None


def test_a_setting_the_port_refuses_is_one_error_and_skipped_by_auto(
        line_tap: tuple[Path, Path, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """A driver that rejects a setting raises termios.error from pyserial: never a traceback."""
    import termios

    from sniffer.errors import RtuSniffError
    from sniffer.line_probe import probe_line

    _, port, _ = line_tap
    real_open = serial.Serial.open

    def refusing_even_parity(self: serial.Serial) -> None:
        if self.parity == serial.PARITY_EVEN:
            raise termios.error(22, "Invalid argument")
        real_open(self)

    monkeypatch.setattr(serial.Serial, "open", refusing_even_parity)
    source = SerialSource(str(port), LineSettings.parse("19200 8E1"))
    with pytest.raises(RtuSniffError, match="cannot open the port with 19200 8E1"):
        source.open()
    # --line auto goes on past the refused setting (and hears nothing on this quiet line).
    with pytest.raises(RtuSniffError, match=r"no traffic heard .*\(1 settings the port refused\)"):
        probe_line(str(port), 0.2, ["19200 8E1", "19200 8N1"])



def test_port_descriptions_are_listed_as_written(cli: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """A port's description is text, not rich markup (which dropped "[usb-ch341]")."""
    monkeypatch.setattr("sniffer.commands.ports.serial_ports",
                        lambda: [("/dev/ttyUSB0", "USB-RS485 adapter [usb-ch341]", "USB VID:PID=1A86:7523")])
    listed = cli("ports")
    assert listed.code == 0 and "USB-RS485 adapter [usb-ch341]" in listed.out
