"""A live bus in Foxglove and Rerun, and recordings followed as they grow: real serial lines
(socat ptys), a real pymodbus master and slave, the real SDKs on both ends."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import serial

from tests.foxglove_client import FoxgloveClient
from tests.ptylab import SOCAT, Relay, pty_pair, pymodbus_slave
from tests.test_capture import HANG_S, REQUEST, RESPONSE, analyze, frames_of, start_capture
from tests.test_streams import foxglove_url, kill_receiver, rerun_receiver, stop_receiver

pytestmark = [
    pytest.mark.skipif(SOCAT is None, reason="needs socat (apt-get install socat; .ci/run installs it)"),
    pytest.mark.filterwarnings("ignore:RRD file has no footer"),
]


def send_paced(port: Path, count: int, sent: bytearray, stop: threading.Event | None = None) -> None:
    """Exchanges at most as fast as 19200 Bd carries them (a pty has no baud rate: a response
    written at once would seem, by its read time, to start before its request ended)."""
    with serial.Serial(str(port), 19200, timeout=0) as line:
        for _ in range(count):
            if stop is not None and stop.is_set():
                return
            line.write(REQUEST)
            sent += REQUEST
            time.sleep(0.012)
            line.write(RESPONSE)
            sent += RESPONSE
            time.sleep(0.03)


def recorded_bytes(path: Path) -> bytes:
    from sniffer.io.registry import open_reader

    reader = open_reader(str(path))
    try:
        return b"".join(batch.data for batch in reader.batches())
    finally:
        reader.close()


def test_a_live_bus_in_foxglove_and_rerun(tmp_path: Path) -> None:
    """pymodbus master and slave; the capture streams to a Foxglove client and a Rerun process
    while it records. Foxglove gets the frames the live JSON Lines and the recording hold."""
    from tests.test_exports import _rerun_rows
    from tests.test_pty_pymodbus import run_master

    recording, received = tmp_path / "live.mcap", tmp_path / "received.rrd"
    viewer, port = rerun_receiver(received)
    try:
        with pty_pair(tmp_path, "master") as to_master, pty_pair(tmp_path, "slave") as to_slave, \
                pty_pair(tmp_path, "tap") as tap:
            capture = start_capture(tap.b, "-o", str(recording), "--format", "jsonl", "--foxglove", "0",
                                    "--rerun", str(port))
            with FoxgloveClient(foxglove_url(capture)) as client:
                assert client.subscribed.wait(HANG_S)
                with pymodbus_slave(to_slave.b), Relay(to_master.b, to_slave.a, copy_to=tap.a):
                    run_master(to_master.a)
                    time.sleep(1.0)
                capture.send_signal(signal.SIGINT)
                out, err = capture.communicate(timeout=HANG_S)
    finally:
        stop_receiver(viewer)
    assert capture.returncode == 130, err
    assert "Traceback" not in err and f"Rerun: streaming to rerun+http://127.0.0.1:{port}/proxy" in err
    live = frames_of([json.loads(line) for line in out.splitlines()])
    streamed = client.json("/modbus/frames")
    key = [(f["hex"], f["role"], f["request_index"], f["flags"]) for f in live]
    assert key and key == [(f["hex"], f["role"], f["request_index"], f["flags"]) for f in streamed]
    code, recorded, _ = analyze(recording)
    assert code == 0 and [f["hex"] for f in frames_of(recorded)] == [f["hex"] for f in live]
    transactions = client.json("/modbus/transactions")
    assert {t["outcome"] for t in transactions} >= {"answered", "exception"}
    _, values, timelines = _rerun_rows(received)
    assert "capture_time" in timelines and any(entity.startswith("/slaves/1/") for entity in values)


def test_viewers_that_hang_or_leave_cost_no_byte(tmp_path: Path) -> None:
    """A Foxglove client that never reads, one that leaves and comes back, a Rerun viewer that is
    killed: the capture goes on, every byte is recorded, the returning client gets new frames."""
    recording, received = tmp_path / "load.mcap", tmp_path / "received.rrd"
    viewer, port = rerun_receiver(received)
    sent = bytearray()
    with pty_pair(tmp_path, "line") as line:
        capture = start_capture(line.b, "-o", str(recording), "--format", "view", "--foxglove", "0",
                                "--rerun", str(port))
        url = foxglove_url(capture)
        with FoxgloveClient(url, read=False) as hanging:
            assert hanging.subscribed.wait(HANG_S)
            leaving = FoxgloveClient(url).__enter__()
            assert leaving.subscribed.wait(HANG_S)
            send_paced(line.a, 40, sent)
            left_with = leaving.wait_for("/modbus/frames", 80, timeout=HANG_S)
            leaving.close()
            kill_receiver(viewer)  # the Rerun viewer goes away mid-capture
            send_paced(line.a, 40, sent)
            with FoxgloveClient(url) as returning:
                assert returning.subscribed.wait(HANG_S)
                time.sleep(0.3)
                send_paced(line.a, 40, sent)
                came_back_with = returning.wait_for("/modbus/frames", 80, timeout=HANG_S)
            capture.send_signal(signal.SIGINT)
            _, err = capture.communicate(timeout=HANG_S)
    assert capture.returncode == 130, err
    assert "Traceback" not in err and "skipped" not in err
    # The SDK's own ERROR lines for the same loss (re_grpc_client, re_sdk) are left out.
    assert "ERROR" not in err and "re_grpc_client" not in err, err
    assert f"warning: Rerun: the viewer at rerun+http://127.0.0.1:{port}/proxy went away" in err
    assert "frames decoded after the viewer went away were not sent to it" in err, err
    assert recorded_bytes(recording) == bytes(sent)
    assert left_with and came_back_with


def test_a_recording_is_followed_as_it_is_written(tmp_path: Path) -> None:
    """``analyze --follow`` of a capture's recording shows frames while the capture runs and ends
    when the capture closes its file: the frames of the finished recording, exit 0."""
    recording = tmp_path / "service.mcap"
    sent = bytearray()
    with pty_pair(tmp_path, "line") as line:
        capture = start_capture(line.b, "-o", str(recording), "--quiet")
        follower = subprocess.Popen([sys.executable, "-m", "sniffer", "analyze", "--follow", str(recording),
                                     "--format", "jsonl"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines: list[str] = []
        reading = threading.Thread(target=lambda: lines.extend(iter(follower.stdout.readline, "")), daemon=True)  # type: ignore[union-attr]
        reading.start()
        send_paced(line.a, 20, sent)
        deadline = time.monotonic() + HANG_S
        while sum('"kind":"frame"' in text for text in lines) < 38 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert follower.poll() is None  # still following
        shown_while_capturing = sum('"kind":"frame"' in text for text in lines)
        capture.send_signal(signal.SIGINT)
        capture.communicate(timeout=HANG_S)
        follower.wait(timeout=HANG_S)
        reading.join(timeout=HANG_S)
    assert shown_while_capturing >= 38
    assert follower.returncode == 0, follower.stderr.read()  # type: ignore[union-attr]
    followed = frames_of([json.loads(text) for text in lines])
    code, recorded, _ = analyze(recording)
    assert code == 0 and len(followed) == 40
    assert [f["hex"] for f in followed] == [f["hex"] for f in frames_of(recorded)]


def test_ctrl_c_ends_following_with_the_statistics_so_far(tmp_path: Path) -> None:
    """A text recording has no end: ``stats --follow`` runs until Ctrl-C, then prints the
    statistics of what was written, exit 0."""
    recording = tmp_path / "service.log"
    sent = bytearray()
    with pty_pair(tmp_path, "line") as line:
        capture = start_capture(line.b, "-o", str(recording), "--quiet")
        send_paced(line.a, 10, sent)
        time.sleep(1.5)  # flushed
        follower = subprocess.Popen([sys.executable, "-m", "sniffer", "stats", "--follow", str(recording),
                                     "--format", "json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        send_paced(line.a, 10, sent)
        time.sleep(2.0)
        follower.send_signal(signal.SIGINT)
        out, err = follower.communicate(timeout=HANG_S)
        capture.send_signal(signal.SIGINT)
        capture.communicate(timeout=HANG_S)
    assert follower.returncode == 0, err
    statistics: dict[str, Any] = json.loads(out)
    assert statistics["frames"] == 40


def test_export_follows_into_foxglove(tmp_path: Path) -> None:
    """The recorder runs as a service; anyone can watch its file in Foxglove."""
    recording = tmp_path / "service.mcap"
    sent = bytearray()
    with pty_pair(tmp_path, "line") as line:
        capture = start_capture(line.b, "-o", str(recording), "--quiet")
        exporter = subprocess.Popen([sys.executable, "-m", "sniffer", "export", "--follow", str(recording),
                                     "--foxglove", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        with FoxgloveClient(foxglove_url(exporter)) as client:
            assert client.subscribed.wait(HANG_S)
            send_paced(line.a, 20, sent)
            assert client.wait_for("/modbus/frames", 40, timeout=HANG_S)
            assert exporter.poll() is None
            capture.send_signal(signal.SIGINT)
            capture.communicate(timeout=HANG_S)
            _, err = exporter.communicate(timeout=HANG_S)
    assert exporter.returncode == 0, err
    assert [json.loads(p)["hex"] for _, p in client.messages["/modbus/frames"]] == \
        [f["hex"] for f in frames_of(analyze(recording)[1])]


@pytest.mark.parametrize(("args", "said"), [
    (["--follow", "captures/atv71-plc-poll.mcap", "captures/xbt-hmi.mcap"], "--follow follows one capture file"),
    (["--follow", "--jobs", "2", "captures/atv71-plc-poll.mcap"], "--jobs 2 with --follow"),
])
def test_follow_option_errors(args: list[str], said: str) -> None:
    result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", *args], capture_output=True, text=True,
                            check=False, cwd=Path(__file__).resolve().parents[1], timeout=HANG_S)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and said in result.stderr, result.stderr


def test_following_a_rotation_goes_on_into_its_next_files(tmp_path: Path) -> None:
    """``--follow site.mcap`` of ``capture -o site.mcap --rotate 2s``: the newest numbered file,
    then each next one as the recorder opens it, frames running on; it ends when no next file
    comes after the capture stopped."""
    recording = tmp_path / "site.mcap"
    sent = bytearray()
    with pty_pair(tmp_path, "line") as line:
        capture = start_capture(line.b, "-o", str(recording), "--quiet", "--rotate", "2s")
        follower = subprocess.Popen([sys.executable, "-m", "sniffer", "analyze", "--follow", str(recording),
                                     "--format", "jsonl"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(6):
            send_paced(line.a, 20, sent)
            time.sleep(0.3)
        time.sleep(1.5)
        capture.send_signal(signal.SIGINT)
        capture.communicate(timeout=HANG_S)
        out, err = follower.communicate(timeout=HANG_S)
    files = sorted(tmp_path.glob("site-*.mcap"))
    assert len(files) >= 3
    assert follower.returncode == 0, err
    followed = frames_of([json.loads(text) for text in out.splitlines()])
    result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", *map(str, files), "--format", "jsonl"],
                            capture_output=True, text=True, check=True)
    chained = frames_of([json.loads(text) for text in result.stdout.splitlines()])
    assert len(followed) == 240 == len(chained)
    assert [(f["index"], f["hex"]) for f in followed] == [(f["index"], f["hex"]) for f in chained]
