"""The table shown in README.md is what `rtusniff analyze` prints for the shipped sample."""

from __future__ import annotations

import re
from collections.abc import Callable

import pytest

from tests.conftest import ROOT, SAMPLE_LOG, CliResult


def test_readme_rows_are_real_output(cli: Callable[..., CliResult], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("COLUMNS", raising=False)
    readme = (ROOT / "README.md").read_text()
    block = readme.split("What the first prints", 1)[1].split("```", 2)[1]
    shown = [line.rstrip() for line in block.splitlines() if re.match(r"^\s+\d+\s+\d\d:", line)]
    assert len(shown) >= 10
    output = {line.rstrip() for line in cli("analyze", str(SAMPLE_LOG)).out.splitlines()}
    for line in shown:
        assert line in output, line
    summary = [line for line in block.splitlines() if " frames, " in line]
    assert summary and summary[0] in output
