"""Sustained load on a live capture: a saturated 115200 Bd line for a while; prints a table.

    python -m benchmarks.bench_capture [--seconds 600]

A socat pseudo-terminal pair is the line. A writer paces FC 3 polling traffic at the
wire speed of 115200 8N1 (11 520 bytes/s, no idle beyond t3.5 between frames) and keeps
a copy of every byte; `rtusniff capture` records the other end, once with --quiet and
once with the live view. Reported: bytes written against bytes recorded (0 lost is the
goal) and the capture process's CPU use (user + system time over the run, from /proc).
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import serial

from decoders.crc import crc_bytes
from sniffer.io.registry import open_reader
from tests.ptylab import pty_pair

BAUD = 115200
BYTES_PER_S = BAUD / 10


def traffic(seed: int = 1) -> bytes:
    rng = random.Random(seed)
    frames = []
    for _ in range(2000):
        slave, count = rng.randint(1, 32), rng.randint(1, 16)
        request = bytes([slave, 3, 0, rng.randrange(200), 0, count])
        response = bytes([slave, 3, 2 * count]) + rng.randbytes(2 * count)
        frames += [request + crc_bytes(request), response + crc_bytes(response)]
    return b"".join(frames)


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(seconds: float, view: bool, folder: Path) -> tuple[int, int, float]:
    recording = folder / f"load-{'view' if view else 'quiet'}.mcap"
    with pty_pair(folder, "load-view" if view else "load-quiet") as pair:
        mode = ["--format", "view"] if view else ["--quiet"]
        capture = subprocess.Popen([sys.executable, "-m", "sniffer", "capture", str(pair.b), "--line", "115200", "8N1",
                                    "-o", str(recording), *mode], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(1.5)
        data = traffic()
        written = 0
        cpu_before = cpu_seconds(capture.pid)
        with serial.Serial(str(pair.a), BAUD, timeout=0) as line:
            start = time.monotonic()
            while (elapsed := time.monotonic() - start) < seconds:
                due = int(elapsed * BYTES_PER_S) - written
                if due > 0:
                    piece = bytes(data[(written + i) % len(data)] for i in range(due))
                    line.write(piece)
                    written += due
                time.sleep(0.005)
            line.flush()
        cpu = cpu_seconds(capture.pid) - cpu_before
        time.sleep(1.5)
        capture.send_signal(signal.SIGINT)
        capture.communicate(timeout=60)
    reader = open_reader(str(recording))
    recorded = sum(len(b.data) for b in reader.batches())
    reader.close()
    return written, recorded, cpu / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=600)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{'mode':<12} {'seconds':>8} {'written':>12} {'recorded':>12} {'lost':>6} {'CPU % of a core':>16}")
        for view in (False, True):
            written, recorded, cpu = run(args.seconds, view, Path(tmp))
            print(f"{'live view' if view else 'quiet':<12} {args.seconds:>8.0f} {written:>12,} {recorded:>12,} "
                  f"{written - recorded:>6} {100 * cpu:>15.1f}%")


if __name__ == "__main__":
    main()
