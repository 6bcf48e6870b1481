"""Live viewers on a live capture: what they cost, what they lose, how late frames reach them.

    python -m benchmarks.bench_live_viewers [--seconds 60]

A socat pseudo-terminal pair is the line (a prompt port: no USB adapter holds reads back).
Two traffics: a saturated 115200 Bd line (FC 3 polling at wire speed, as
``bench_capture``) and a master polling at 19200 Bd with 50 ms between exchanges. For
each, `rtusniff capture -o FILE --format view` runs

* alone (the capture benchmark's budget),
* with ``--foxglove`` and ``--rerun``: a Foxglove WebSocket client reading everything and a
  Rerun process saving what it receives,
* with a Foxglove client that subscribes and never reads again, and the Rerun process killed
  half way.

Printed per run: bytes written and recorded (lost: the goal is 0), the capture's CPU (user +
system over the run, from /proc) and, where a client reads, the latency from the read that
returned a frame's last byte (the frame's ``t_end_ns``) to the message's arrival at the
client (``time.time_ns``, over loopback: an upper bound of it leaving the process).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import select
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import serial

from benchmarks.bench_capture import cpu_seconds
from benchmarks.bench_capture import traffic as saturated_traffic
from decoders.crc import crc_bytes
from sniffer.io.registry import open_reader
from tests.foxglove_client import FoxgloveClient
from tests.ptylab import pty_pair
from tests.test_streams import kill_receiver, rerun_receiver, stop_receiver


@dataclass
class Traffic:
    name: str
    baud: int
    #: Frames as the master and slaves write them, and the pause after each (s).
    frames: list[tuple[bytes, float]]


def polling(seed: int = 2) -> Traffic:
    rng = random.Random(seed)
    frames = []
    for _ in range(4000):
        slave, count = rng.randint(1, 16), rng.randint(1, 8)
        request = bytes([slave, 3, 0, rng.randrange(200), 0, count])
        response = bytes([slave, 3, 2 * count]) + rng.randbytes(2 * count)
        # The answer after its request has been carried at 19200 Bd and a 5 ms turnaround.
        frames += [(request + crc_bytes(request), 0.005 + 8 * 10 / 19200),
                   (response + crc_bytes(response), 0.050 + (5 + 2 * count) * 10 / 19200)]
    return Traffic("polling 19200 Bd, 50 ms idle", 19200, frames)


def saturated() -> Traffic:
    data = saturated_traffic()
    return Traffic("saturated 115200 Bd", 115200, [(data, 0.0)])


def write_traffic(port: Path, traffic: Traffic, seconds: float) -> int:
    """Writes for ``seconds``, never faster than the baud rate carries it; returns bytes written."""
    written = 0
    rate = traffic.baud / 10
    with serial.Serial(str(port), traffic.baud, timeout=0) as line:
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            for frame, pause in traffic.frames:
                if len(traffic.frames) == 1:  # one stream: paced in pieces at the wire rate
                    for offset in range(0, len(frame), 64):
                        due = start + (written + 64) / rate
                        time.sleep(max(0.0, due - time.monotonic()))
                        line.write(frame[offset : offset + 64])
                        written += len(frame[offset : offset + 64])
                        if time.monotonic() - start >= seconds:
                            return written
                    continue
                line.write(frame)
                written += len(frame)
                time.sleep(pause)
                if time.monotonic() - start >= seconds:
                    return written
    return written


def run(traffic: Traffic, mode: str, seconds: float, folder: Path) -> dict[str, object]:
    recording = folder / f"{mode}-{traffic.baud}.mcap"
    env = {**os.environ, "CI": "1"}
    rerun = rerun_port = None
    extra: list[str] = []
    if mode != "alone":
        rerun, rerun_port = rerun_receiver(folder / f"{mode}.rrd")
        extra = ["--foxglove", "0", *([] if os.environ.get("BENCH_NO_RERUN") else ["--rerun", str(rerun_port)])]
    with pty_pair(folder, f"{mode}-{traffic.baud}") as pair:
        capture = subprocess.Popen([sys.executable, "-m", "sniffer", "capture", str(pair.b), "--line",
                                    f"{traffic.baud} 8N1", "-o", str(recording), "--format", "view", *extra],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        url = _foxglove_url(capture) if extra else None
        client = FoxgloveClient(url, read=mode != "hanging") if url else None
        if client is not None:
            client.__enter__()
            client.subscribed.wait(30)
        time.sleep(1.0)
        cpu_before = cpu_seconds(capture.pid)
        if mode == "hanging" and rerun is not None:
            half = write_traffic(pair.a, traffic, seconds / 2)
            kill_receiver(rerun)  # the viewer binary, not only the script that started it
            written = half + write_traffic(pair.a, traffic, seconds / 2)
        else:
            written = write_traffic(pair.a, traffic, seconds)
        cpu = cpu_seconds(capture.pid) - cpu_before
        time.sleep(1.5)
        capture.send_signal(signal.SIGINT)
        _, err = capture.communicate(timeout=120)
        if client is not None:
            client.close()
    if rerun is not None and rerun.poll() is None:
        stop_receiver(rerun)
    reader = open_reader(str(recording))
    recorded = sum(len(b.data) for b in reader.batches())
    reader.close()
    result: dict[str, object] = {"written": written, "recorded": recorded, "cpu": cpu / seconds,
                                 "failed": "Traceback" in err}
    if client is not None and mode == "viewers":
        frames = client.messages["/modbus/frames"]
        latencies = sorted((arrival - json.loads(payload)["t_end_ns"]) / 1e6
                           for arrival, (_, payload) in zip(client.arrivals_ns["/modbus/frames"], frames, strict=True))
        result.update(frames=len(frames), p50=latencies[len(latencies) // 2],
                      p99=latencies[int(len(latencies) * 0.99)], max=latencies[-1])
    return result


def _foxglove_url(process: subprocess.Popen[str]) -> str:
    assert process.stderr is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stderr], [], [], 0.1)
        if ready:
            found = re.search(r"Foxglove: open (ws://\S+)", process.stderr.readline())
            if found:
                return found.group(1)
    raise RuntimeError("the capture never said where it serves Foxglove")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60)
    args = parser.parse_args()
    print(f"{'traffic':<30} {'viewers':<34} {'written':>10} {'lost':>5} {'CPU %':>6} "
          f"{'frames':>7} {'p50 ms':>7} {'p99 ms':>7} {'max ms':>7}")
    modes = {"alone": "none", "viewers": "Foxglove + Rerun, reading",
             "hanging": "Foxglove never reads, Rerun killed"}
    with tempfile.TemporaryDirectory() as tmp:
        for traffic in (polling(), saturated()):
            for mode, said in modes.items():
                r = run(traffic, mode, args.seconds, Path(tmp))
                lost = int(r["written"]) - int(r["recorded"])  # type: ignore[call-overload]
                latency = (f"{r['frames']:>7,} {r['p50']:>7.1f} {r['p99']:>7.1f} {r['max']:>7.1f}"
                           if "p50" in r else f"{'':>7} {'':>7} {'':>7} {'':>7}")
                print(f"{traffic.name:<30} {said:<34} {r['written']:>10,} {lost:>5} "
                      f"{100 * float(r['cpu']):>5.1f}% {latency}{'  (traceback!)' if r['failed'] else ''}",
                      flush=True)


if __name__ == "__main__":
    main()
