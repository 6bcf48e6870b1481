"""``benchmarks/function_clock.py``, which measures where a command's main thread spends its
time: it times the functions named, where they are defined and where imported by name, and
leaves the command's exit code and output as they are."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from tests.conftest import CAPTURES

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "function_clock.py"


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False,
                          timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})


def test_the_functions_named_are_timed_and_the_command_runs(tmp_path: Path) -> None:
    done = _run("decoders.modbus.annotate:find_columnar,sniffer.exports.parquet_values:ValueCollector.messages",
                "export", str(CAPTURES / "atv71-plc-poll.mcap"), "--parquet", str(tmp_path / "set"), "-q")
    assert done.returncode == 0, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert re.fullmatch(r"find_columnar=\d+\.\d{3} ValueCollector\.messages=\d+\.\d{3} main=\d+\.\d{2}", last), last
    assert list((tmp_path / "set" / "frames").rglob("*.parquet"))


def test_without_a_command_it_says_how_to_use_it() -> None:
    done = _run()
    assert done.returncode == 2
    assert "MODULE:QUALNAME" in done.stderr
