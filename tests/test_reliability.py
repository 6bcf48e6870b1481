"""A short slice of the reliability benchmark (``benchmarks/bench_reliability.py``): every
hostile family once, each run one line and a documented exit code, nothing altered."""

from __future__ import annotations

import pytest

from benchmarks import bench_reliability


def test_a_slice_of_every_hostile_family(capsys: pytest.CaptureFixture[str]) -> None:
    code = bench_reliability.main(["--per-family", "1", "--quick", "--seed", "3"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    rows = {line.split()[0]: line.split() for line in printed.splitlines()[1:] if not line.startswith(" ")}
    families = {"truncation", "bit", "crafted", "hostile", "full", "line", "logic,", "MCAP", "outputs,", "report,"}
    assert families <= set(rows)
    destroyed = [int(row[-2]) for row in rows.values()]
    assert not any(destroyed), printed
