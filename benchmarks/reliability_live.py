"""The live families of the reliability benchmark, on socat pseudo-terminals: two captures on one
port, ``kill -9`` of a recording capture, a consumer of ``--format jsonl`` that stops reading, and
a disk that fills up during a capture.

Each scenario is one input of the family ``live``; what it checks goes in the family's problems.
"""

from __future__ import annotations

import json
import select
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import serial

from benchmarks.bench_reliability import Family
from tests.ptylab import SOCAT, pty_pair

REQUEST = bytes.fromhex("02030C1E0004276C")
RESPONSE = bytes.fromhex("0203080028025801F4000052B0")
WAIT_S = 60


def live(scratch: Path) -> Family:
    family = Family("live (pty)")
    if SOCAT is None:
        family.problems.append("skipped: socat is not installed")
        return family
    for scenario in (_two_readers, _kill_9, _slow_consumer, _full_disk):
        for left in ("first.mcap", "second.mcap", "killed.mcap", "slow.mcap", "full.mcap"):  # of an earlier run
            (scratch / left).unlink(missing_ok=True)
        with pty_pair(scratch, scenario.__name__.strip("_")) as pair:
            family.runs += 1
            try:
                scenario(family, scratch, pair.a, pair.b)
            except (AssertionError, subprocess.TimeoutExpired) as exc:
                family.problems.append(f"{scenario.__name__.strip('_')}: {exc}")
    return family


def _capture(port: Path, *args: str, stdout: Any = subprocess.PIPE, **options: Any) -> subprocess.Popen[bytes]:
    process = subprocess.Popen([sys.executable, "-m", "sniffer", "capture", str(port), "--line", "19200", "8N1", *args],
                               stdout=stdout, stderr=subprocess.PIPE, **options)
    assert process.stderr is not None
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stderr], [], [], 0.1)
        if ready and process.stderr.readline().startswith(b"capturing "):
            return process
        assert process.poll() is None, "the capture ended before it said it was capturing"
    process.kill()
    raise AssertionError("the capture never said it was capturing")


def _send(line: Path, count: int, pause_s: float) -> None:
    with serial.Serial(str(line), 19200, timeout=0) as port:
        for _ in range(count):
            port.write(REQUEST)
            time.sleep(0.002)
            port.write(RESPONSE)
            time.sleep(pause_s)


def _frames(path: Path) -> list[dict[str, Any]]:
    done = subprocess.run([sys.executable, "-m", "sniffer", "analyze", str(path), "--format", "jsonl"],
                          capture_output=True, check=False, timeout=WAIT_S)
    assert done.returncode == 0, done.stderr.decode(errors="replace")[-300:]
    return [r for r in map(json.loads, done.stdout.splitlines()) if r["kind"] == "frame"]


def _two_readers(family: Family, scratch: Path, line: Path, port: Path) -> None:
    first = _capture(port, "-o", str(scratch / "first.mcap"), "--quiet")
    family.runs += 1
    second = subprocess.run([sys.executable, "-m", "sniffer", "capture", str(port), "--line", "19200", "8N1", "-o",
                             str(scratch / "second.mcap")], capture_output=True, timeout=WAIT_S, check=False)
    said = second.stderr.decode(errors="replace")
    assert second.returncode == 4 and said.count("\n") == 1, f"second capture: exit {second.returncode}, {said!r}"
    _send(line, 20, 0.02)
    time.sleep(0.5)
    first.terminate()
    first.communicate(timeout=WAIT_S)
    good = [f for f in _frames(scratch / "first.mcap") if f["crc_ok"]]
    assert len(good) == 40, f"the first capture recorded {len(good)} of 40 frames"
    (scratch / "first.mcap").unlink()


def _kill_9(family: Family, scratch: Path, line: Path, port: Path) -> None:
    recording = scratch / "killed.mcap"
    capture = _capture(port, "-o", str(recording), "--quiet")
    _send(line, 20, 0.02)
    time.sleep(2.5)  # two flushes after the last byte
    capture.kill()
    capture.wait(timeout=WAIT_S)
    good = [f for f in _frames(recording) if f["crc_ok"]]
    if len(good) != 40:
        family.altered += 1
    assert len(good) == 40, f"after kill -9 the recording holds {len(good)} of 40 frames"
    recording.unlink()


def _slow_consumer(family: Family, scratch: Path, line: Path, port: Path) -> None:
    """Nobody reads the JSONL for a while: reads are skipped for decoding, said, never spliced."""
    recording = scratch / "slow.mcap"
    capture = _capture(port, "-o", str(recording), "--format", "jsonl")
    sender = threading.Thread(target=_send, args=(line, 3000, 0.0005))
    sender.start()
    sender.join()
    time.sleep(1.0)
    capture.terminate()
    out, err = capture.communicate(timeout=WAIT_S)
    records = [json.loads(line) for line in out.splitlines()]
    frames = [r for r in records if r["kind"] == "frame"]
    summary = records[-1]
    recorded = [f for f in _frames(recording) if f["crc_ok"]]
    if len(recorded) != 6000:
        family.altered += 1
    assert len(recorded) == 6000, f"the recording holds {len(recorded)} of 6000 frames"
    skipped = summary.get("skipped_reads", 0)
    gaps = sum(1 for r in records if r["kind"] == "gap")
    assert (skipped > 0) == (gaps > 0), f"{skipped} skipped reads but {gaps} gap records"
    if skipped:
        assert b"skipped" in err, "no warning on standard error"
    invented = [f for f in frames if (f["role"] in ("noise", "unknown") or not f["crc_ok"])
                and "truncated" not in f["flags"]]
    assert not invented, f"{len(invented)} frames never on the wire (noise, CRC errors) in the JSONL"
    recording.unlink()


def _small_disk() -> None:
    """The child's files may grow to 3 000 bytes: a disk that fills up (RLIMIT_FSIZE)."""
    import resource
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (3000, 3000))


def _full_disk(family: Family, scratch: Path, line: Path, port: Path) -> None:
    """The disk fills during a capture: exit 11 in one line, the recording readable up to its last flush."""
    import os

    recording = scratch / "full.mcap"
    capture = _capture(port, "-o", str(recording), "--quiet", "--duration", "20", preexec_fn=_small_disk)
    _send(line, 5, 0.02)
    time.sleep(1.5)  # a flush with whole frames in it
    with serial.Serial(str(line), 19200, timeout=0) as writer:
        for _ in range(30):
            writer.write(os.urandom(200))  # bytes that do not compress: the "disk" fills up
            time.sleep(0.1)
    _, err = capture.communicate(timeout=WAIT_S)
    said = err.decode(errors="replace")
    assert capture.returncode == 11 and "kept up to its last flush" in said, f"exit {capture.returncode}: {said!r}"
    good = [f for f in _frames(recording) if f["crc_ok"]]
    if len(good) < 10:
        family.altered += 1
    assert len(good) >= 10, f"the recording kept {len(good)} of the 10 frames flushed before the disk filled"
    recording.unlink()
