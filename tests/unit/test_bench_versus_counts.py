"""``bench_versus --instructions``: the instructions a command executes, counted by callgrind in
each of its processes, read from callgrind's own output files."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from benchmarks.bench_versus import ROOT, _counted, callgrind_total

CALLGRIND_OUTPUT = """# callgrind format
version: 1
creator: callgrind-3.22.0
pid: 16003
cmd:  python -m sniffer --version
events: Ir
summary: 118433409
fl=(1) ???
fn=(1) _start
0 12
totals: 118433409
"""


def test_the_total_is_read_from_the_totals_line() -> None:
    assert callgrind_total(CALLGRIND_OUTPUT) == 118_433_409
    assert callgrind_total(CALLGRIND_OUTPUT.replace("totals: 118433409\n", "")) == 118_433_409  # summary alone
    with pytest.raises(ValueError, match="no totals"):
        callgrind_total("events: Ir\nfn=(1) main\n0 3\n")


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_a_command_is_counted_alike_twice(tmp_path: Path) -> None:
    first, second = (_counted(ROOT, ["--version"], tmp_path) for _ in range(2))
    assert 0.02 < first["wall"] < 2  # billions: the interpreter's start and rtusniff's imports
    assert first["children"] == 0  # --version starts no process
    assert abs(first["wall"] - second["wall"]) < 0.005 * first["wall"]
    assert not list(tmp_path.iterdir())  # callgrind's files removed
