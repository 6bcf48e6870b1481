"""The benchmark capture generator: reproducible from its seed, and as mixed as it says."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from benchmarks.generate_capture import write
from decoders.line import LineSettings
from tests.conftest import CliResult

Cli = Callable[..., CliResult]
LINE = LineSettings.parse("115200 8N1")


def test_same_seed_same_capture_and_every_fault(cli: Cli, tmp_path: Path) -> None:
    first, second, other = tmp_path / "a.mcap", tmp_path / "b.mcap", tmp_path / "c.mcap"
    write(first, 20_000, 7, LINE, "exact")
    write(second, 20_000, 7, LINE, "exact")
    write(other, 20_000, 8, LINE, "exact")
    frames = [cli("analyze", str(p), "--format", "jsonl").out.splitlines()[1:] for p in (first, second, other)]
    assert frames[0] == frames[1] != frames[2]
    stats = json.loads(cli("stats", str(first), "--format", "json").out)
    assert 19_900 <= stats["frames"] <= 20_300
    assert {"gap_1_5", "short_idle", "timeout", "retry"} <= set(stats["flags"])
    assert stats["crc_errors"] > 0 and stats["roles"]["exception"] > 0 and stats["noise_bytes"] > 0
    functions = {row["function"] for row in stats["per_slave_function"]}
    assert {3, 6, 16, 23, 43} <= functions


@pytest.mark.parametrize("timing", ["host", "read-timeout", "random-sizes"])
def test_host_timing_records_the_same_frames(cli: Cli, tmp_path: Path, timing: str) -> None:
    """Through a USB adapter or a pyserial read loop, every CRC-valid frame of the exact
    capture is found, and no other."""
    exact, host = tmp_path / "exact.mcap", tmp_path / "host.mcap"
    write(exact, 4_000, 3, LINE, "exact")
    write(host, 4_000, 3, LINE, timing)
    records = [cli("analyze", str(p), "--format", "jsonl").jsonl() for p in (exact, host)]
    valid = [[r["hex"] for r in rs if r["kind"] == "frame" and r["crc_ok"] and r["role"] != "noise"] for rs in records]
    assert records[1][0]["timing"] == "host"
    assert valid[1] == valid[0]
