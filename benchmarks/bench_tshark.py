"""rtusniff against Wireshark's tshark on the same frames, side by side in one run; prints a table.

    python -m benchmarks.bench_tshark [--frames 1000000] [--keep DIR] [--traffic polling|mixed|steady|coils|wide]

The capture is FC 3 polling at 115200 8N1 (benchmarks/bench_memory.py). rtusniff writes it as
pcap (`export --pcap`, frames already split), and tshark decodes that pcap with its Modbus RTU
dissector (DLT 147 mapped to mbrtu on its command line, CRC check on) into ``-T fields``: the
fairest like-for-like, since tshark cannot split a raw byte stream into RTU frames itself.
Every command runs in its own process; times are wall clock, RSS the process's peak. The
table against tshark's default one-line summary is the terminal view against the terminal view.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import add_capture_options, benchmark_capture, compile_sources, wire_megabytes
from sniffer.exports.pcap_export import WIRESHARK_USER_DLT

TSHARK_FIELDS = ["frame.number", "frame.time_epoch", "mbrtu.unit_id", "modbus.func_code", "mbrtu.crc16.status",
                 "modbus.regval_uint16"]


def run(argv: list[str], output: Path) -> tuple[float, float]:
    """Seconds and peak RSS (MB) of one command, its stdout going to ``output``."""
    with output.open("wb") as sink:
        start = time.perf_counter()
        process = subprocess.Popen(argv, stdout=sink, stderr=subprocess.PIPE, env={**os.environ, "CI": "1"})
        _, status, usage = os.wait4(process.pid, 0)
        seconds = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode != 0:
        sys.exit(f"bench_tshark: {argv[0]} failed: {process.stderr.read().decode() if process.stderr else ''}")
    return seconds, usage.ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--rounds", type=int, default=1,
                        help="run every command this many times, in rounds; the table gives medians")
    add_capture_options(parser)
    args = parser.parse_args()
    tshark = shutil.which("tshark")
    if tshark is None:
        sys.exit("bench_tshark: tshark is not installed (apt-get install tshark)")
    rtusniff = [sys.executable, "-m", "sniffer"]
    compile_sources()
    with tempfile.TemporaryDirectory() as tmp:
        capture = benchmark_capture(args.keep or Path(tmp), args.frames, args.traffic)
        pcap = Path(tmp) / "capture.pcap"
        fields = [a for f in TSHARK_FIELDS for a in ("-e", f)]
        jobs = [
            ("rtusniff stats --format json", [*rtusniff, "stats", str(capture), "--format", "json"]),
            ("rtusniff analyze --format jsonl", [*rtusniff, "analyze", str(capture), "--format", "jsonl"]),
            ("rtusniff analyze (table, a line a frame)", [*rtusniff, "analyze", str(capture)]),
            # Link type 147, the frames alone: what tshark's DLT_USER mapping below decodes as Modbus RTU.
            ("rtusniff export --pcap", [*rtusniff, "export", str(capture), "--pcap", str(pcap), "--pcap-link", "user",
                                        "--force"]),
            ("rtusniff export --mcap", [*rtusniff, "export", str(capture), "--mcap", str(Path(tmp) / "x.mcap"),
                                        "--force", "-q"]),
            ("rtusniff export --parquet", [*rtusniff, "export", str(capture), "--parquet",
                                           str(Path(tmp) / "dataset"), "-q"]),
            ("tshark -T json (mbrtu, on that pcap)",
             [tshark, "-n", "-o", f"uat:user_dlts:{WIRESHARK_USER_DLT}", "-o", "mbrtu.crc_verification:TRUE",
              "-r", str(pcap), "-T", "json"]),
            ("tshark -T fields (mbrtu, on that pcap)",
             [tshark, "-n", "-o", f"uat:user_dlts:{WIRESHARK_USER_DLT}", "-o", "mbrtu.crc_verification:TRUE",
              "-r", str(pcap), "-T", "fields", *fields]),
            ("tshark one-line summary (its default)",
             [tshark, "-n", "-o", f"uat:user_dlts:{WIRESHARK_USER_DLT}", "-o", "mbrtu.crc_verification:TRUE",
              "-r", str(pcap)]),
        ]
        wire_mb = wire_megabytes(capture)
        print(f"{args.frames:,} frames, {wire_mb:.1f} MB on the wire, {capture.stat().st_size / 1e6:.1f} MB capture, "
              f"{args.rounds} round{'s' if args.rounds != 1 else ''} (medians)")
        rounds = [_round(jobs, Path(tmp), count_lines=number == 0) for number in range(args.rounds)]
        _print_table(jobs, rounds, args.frames, wire_mb)
        _print_ratios(jobs, rounds)


#: A round's figures per job: seconds, peak RSS (MB), output lines (first round only, else -1).
Round = dict[str, tuple[float, float, int]]


def _round(jobs: list[tuple[str, list[str]]], folder: Path, *, count_lines: bool) -> Round:
    """Every job once, in order (the pcap export before tshark reads it), into a new dataset."""
    shutil.rmtree(folder / "dataset", ignore_errors=True)
    figures = {}
    for name, argv in jobs:
        output = folder / "out.txt"
        seconds, rss = run(argv, output)
        lines = -1
        if count_lines:
            with output.open("rb") as f:
                lines = sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
        figures[name] = (seconds, rss, lines)
    return figures


def _print_table(jobs: list[tuple[str, list[str]]], rounds: list[Round], frames: int, wire_mb: float) -> None:
    print(f"{'command':<40} {'seconds':>8} {'frames/s':>10} {'wire MB/s':>10} {'peak RSS MB':>12} "
          f"{'output lines':>13}")
    for name, _ in jobs:
        seconds = statistics.median(r[name][0] for r in rounds)
        rss = max(r[name][1] for r in rounds)
        print(f"{name:<40} {seconds:>8.1f} {frames / seconds:>10,.0f} {wire_mb / seconds:>10.2f} "
              f"{rss:>12.1f} {rounds[0][name][2]:>13,}")


def _print_ratios(jobs: list[tuple[str, list[str]]], rounds: list[Round]) -> None:
    """tshark's time over rtusniff's, per round (the two ran minutes apart at most), then the
    median of the rounds: on a shared machine whose speed drifts, a ratio of medians taken
    over different minutes says less."""
    fields, line = jobs[-2][0], jobs[-1][0]
    pairs = [(fields, "rtusniff stats --format json"), (fields, "rtusniff analyze --format jsonl")]
    pairs += [("tshark -T json (mbrtu, on that pcap)", name)
              for name in ("rtusniff analyze --format jsonl", "rtusniff export --mcap", "rtusniff export --parquet")]
    pairs.append((line, "rtusniff analyze (table, a line a frame)"))
    for theirs, ours in pairs:
        ratios = [r[theirs][0] / r[ours][0] for r in rounds]
        spread = f" (rounds {min(ratios):.2f}..{max(ratios):.2f})" if len(ratios) > 1 else ""
        label = theirs.split(" (")[0].replace("tshark one-line summary", "tshark one-line")
        print(f"{label} time / {ours} time: {statistics.median(ratios):.2f}{spread}")


if __name__ == "__main__":
    main()
