"""A short coverage-guided run of every atheris target (tests/fuzz/atheris_fuzz.py); the long
run is by hand (README, "Fuzzing")."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tests.conftest import ROOT

HARNESS = ROOT / "tests" / "fuzz" / "atheris_fuzz.py"


#: Runs per target, a slice of CI's time: the profile parser is slow per input (tomllib), its
#: slice is shorter. The long runs are by hand (docs/development.md).
RUNS = {"text": 1500, "mcap": 1500, "framer": 1500, "decoders": 1500, "profile": 400, "sigrok": 200, "pcap": 400,
        "sigrok-cli": 400, "mcap-metadata": 250}
#: A module each target's code under test imports only when first used: it must carry coverage
#: counters all the same (atheris instruments only what is imported inside its block).
REACHED = {"text": "sniffer.io.formats.text", "mcap": "sniffer.io.mcap_native", "framer": "decoders.framing.fast",
           "decoders": "decoders.modbus.columnar", "profile": "decoders.profiles.parse",
           "sigrok": "sniffer.io.sigrok_session", "pcap": "sniffer.io.pcap_reader",
           "sigrok-cli": "sniffer.io.sigrok_annotations", "mcap-metadata": "sniffer.io.mcap_checks"}


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
    instrumented = set(re.findall(r"^INFO: Instrumenting (\S+)$", result.stderr, re.MULTILINE))
    assert REACHED[target] in instrumented
    assert not any(name.split(".")[0] in ("numpy", "pyarrow", "hypothesis") for name in instrumented)
