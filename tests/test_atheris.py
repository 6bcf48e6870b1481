"""A short coverage-guided run of every atheris target (tests/fuzz/atheris_fuzz.py); the long
run is by hand (README, "Fuzzing")."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.conftest import ROOT

HARNESS = ROOT / "tests" / "fuzz" / "atheris_fuzz.py"


@pytest.mark.parametrize("target", ["text", "mcap", "framer", "decoders"])
def test_atheris_target_runs_clean(target: str, tmp_path: object) -> None:
    pytest.importorskip("atheris")
    result = subprocess.run([sys.executable, str(HARNESS), target, "-runs=3000", "-max_len=4096", "-seed=1"],
                            capture_output=True, text=True, check=False, timeout=300, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    assert "Done 3000 runs" in result.stderr
