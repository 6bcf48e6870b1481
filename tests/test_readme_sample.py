"""The table shown in README.md is what `rtusniff analyze` prints for the shipped sample on a
terminal 120 columns wide (``--width 120`` lays it out the same into a pipe)."""

from __future__ import annotations

import re
from collections.abc import Callable

import pytest

from tests.conftest import ROOT, SAMPLE_LOG, CliResult


def test_readme_rows_are_real_output(cli: Callable[..., CliResult], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # the README names the sample as the set-up command does
    readme = (ROOT / "README.md").read_text()
    block = readme.split("What the first prints", 1)[1].split("```", 2)[1]
    shown = [line.rstrip() for line in block.splitlines() if line.strip() and line.strip() != "…"]
    assert sum(1 for line in shown if re.match(r"^\s*\d+\s+\d\d:", line)) >= 10
    output = cli("analyze", str(SAMPLE_LOG.relative_to(ROOT)), "--width", "120").out
    lines = {line.rstrip() for line in output.splitlines()}
    for line in shown:
        assert line in lines, line
    # Every shown row is whole: its continuation lines follow it as in the output.
    assert "\n".join(shown[3:5]) in output
