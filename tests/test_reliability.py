"""A short slice of the reliability benchmark (``benchmarks/bench_reliability.py``): every
hostile family once, each run one line and a documented exit code, nothing altered or destroyed.
One test per family, so that the families run side by side."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import bench_reliability

FAMILIES = [name for name, _ in bench_reliability.families(Path("."), 1, 3, quick=True)]


def test_the_slice_holds_every_family_ci_runs() -> None:
    assert FAMILIES == ["truncation", "bit flips", "crafted MCAP", "hostile sizes", "hostile profiles", "full disk",
                        "line names", "logic, pcap", "MCAP metadata", "outputs, inputs", "report, dataset"]


@pytest.mark.parametrize("family", FAMILIES)
def test_a_slice_of_a_hostile_family(family: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = bench_reliability.main(["--per-family", "1", "--quick", "--seed", "3", "--family", family])
    printed = capsys.readouterr().out
    assert code == 0, printed
    (row,) = [line for line in printed.splitlines()[1:] if not line.startswith(" ")]
    assert row.startswith(family) and int(row.split()[-2]) == 0, printed  # nothing destroyed
