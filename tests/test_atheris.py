"""A short coverage-guided run of every atheris target (tests/fuzz/atheris_fuzz.py); the long
run is by hand (README, "Fuzzing")."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tests.conftest import ROOT

HARNESS = ROOT / "tests" / "fuzz" / "atheris_fuzz.py"


#: Runs per target: the profile parser is slow per input (tomllib), its slice is shorter.
RUNS = {"text": 3000, "mcap": 3000, "framer": 3000, "decoders": 3000, "profile": 800}


@pytest.mark.parametrize("target", list(RUNS))
def test_atheris_target_runs_clean(target: str, tmp_path: object) -> None:
    pytest.importorskip("atheris")
    runs = RUNS[target]
    result = subprocess.run([sys.executable, str(HARNESS), target, f"-runs={runs}", "-max_len=4096", "-seed=1"],
                            capture_output=True, text=True, check=False, timeout=300, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    # libFuzzer may report one run more than -runs asked for (seen in CI: "Done 801 runs" for 800).
    done = re.search(r"Done (\d+) runs", result.stderr)
    assert done is not None and int(done.group(1)) >= runs, result.stderr[-3000:]
