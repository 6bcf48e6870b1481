"""How Wireshark classifies rtusniff's pcaps, per shipped sample and real recording: the frames
alone (``--pcap-link user``, link type 147) against the default UDP encapsulation read with the
profile ``rtusniff``; and whether its CRC verdicts are rtusniff's.

    python -m benchmarks.wireshark_counts

Needs tshark. Runs ``rtusniff wireshark setup`` into a temporary home first.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "real" / "sigrok-cli-text"
USER_DLT = 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""'


def run(args: list[str], env: dict[str, str]) -> str:
    return subprocess.run(args, capture_output=True, text=True, env=env, check=True, timeout=600).stdout


def main() -> None:
    home = Path(tempfile.mkdtemp())
    env = {**os.environ, "HOME": str(home), "XDG_CONFIG_HOME": str(home / ".config")}
    rtusniff = [sys.executable, "-m", "sniffer"]
    run([*rtusniff, "wireshark", "setup"], env)
    captures = sorted((ROOT / "captures").glob("*.log")) + sorted(REAL.glob("*.log"))
    print(f"{'capture':42} {'frames':>6} {'modbus':>6} {'unclassified: user':>18} {'udp+profile':>11} "
          f"{'CRC verdicts differ':>19}")
    for capture in captures:
        records = [json.loads(line) for line in run([*rtusniff, "analyze", str(capture), "--format", "jsonl"],
                                                    env).splitlines()]
        frames = [r for r in records if r["kind"] == "frame"]
        modbus = [r for r in frames if r["protocol"] == "modbus" and r["role"] != "noise"]
        counts = []
        for link, options in (("user", ["-o", USER_DLT]), ("udp", ["-C", "rtusniff"])):
            pcap = home / f"{capture.stem}-{link}.pcapng"
            run([*rtusniff, "export", str(capture), "--pcap", str(pcap), "--pcap-link", link, "-q"], env)
            rows = run(["tshark", "-n", *options, "-o", "mbrtu.crc_verification:TRUE", "-r", str(pcap), "-T",
                        "fields", "-E", "separator=;", "-e", "mbrtu.crc16.status", "-e", "_ws.col.Info"],
                       env).splitlines()
            unclassified = sum("Unable to classify" in row for row in rows)
            differ = sum(1 for row, frame in zip(rows, frames, strict=True)
                         if frame in modbus and row.split(";")[0] != ("1" if frame["crc_ok"] else "0"))
            counts.append((unclassified, differ))
        print(f"{capture.name:42} {len(frames):6} {len(modbus):6} {counts[0][0]:18} {counts[1][0]:11} "
              f"{counts[1][1]:19}")


if __name__ == "__main__":
    main()
