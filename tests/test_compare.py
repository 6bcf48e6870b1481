"""``rtusniff compare``: a capture against itself is the same everywhere; a slave that stops
answering is worse (and better the other way round); the JSON has both sides' measures; the
table of the shipped samples is a golden file (RTUSNIFF_REGENERATE_GOLDEN=1 to regenerate)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

from tests.conftest import ROOT, CliResult

Cli = Callable[..., CliResult]
SAMPLE = ROOT / "captures" / "atv71-plc-poll.log"
GOLDEN = Path(__file__).parent / "golden" / "compare" / "atv71-exact-vs-usb.txt"


def without_answers_of_slave_12(tmp_path: Path) -> Path:
    """The sample with slave 12's register answers gone (``0C 03 06 …``): its reads time out."""
    lines = [line for line in SAMPLE.read_text().splitlines() if " 0C 03 06 " not in line]
    path = tmp_path / "silent-12.log"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_capture_against_itself_is_the_same(cli: Cli) -> None:
    result = cli("compare", str(SAMPLE), str(SAMPLE), "--format", "json")
    assert result.code == 0, result.err
    document = json.loads(result.out)
    assert {row["verdict"] for row in document["per_slave_function"]} == {"same"}
    assert document["before"]["frames"] == document["after"]["frames"] == 52


def test_a_slave_that_stops_answering_is_worse(cli: Cli, tmp_path: Path) -> None:
    silent = without_answers_of_slave_12(tmp_path)
    worse = json.loads(cli("compare", str(SAMPLE), str(silent), "--format", "json").out)
    [row] = [r for r in worse["per_slave_function"] if (r["slave"], r["function"]) == (12, 3)]
    assert row["verdict"] == "worse" and row["after"]["timeouts"] > row["before"]["timeouts"]
    assert row["after"]["error_rate"] > row["before"]["error_rate"]
    assert {r["verdict"] for r in worse["per_slave_function"] if r["slave"] != 12} == {"same"}
    better = json.loads(cli("compare", str(silent), str(SAMPLE), "--format", "json").out)
    assert [r["verdict"] for r in better["per_slave_function"] if (r["slave"], r["function"]) == (12, 3)] == \
        ["better"]
    table = cli("compare", str(SAMPLE), str(silent))
    assert "1 worse" in table.out and "# per slave and function, before→after" in table.out
    line = next(row for row in table.out.splitlines() if row.split()[:2] == ["12", "3"])
    assert line.split()[9] == "worse"  # one field per cell into a pipe


def test_the_sample_against_its_usb_recording(cli: Cli) -> None:
    result = cli("compare", str(SAMPLE), str(ROOT / "captures" / "atv71-plc-poll-usb.log"), "--width", "100")
    assert result.code == 0, result.err
    text = result.out.replace(str(ROOT) + "/", "")
    if os.environ.get("RTUSNIFF_REGENERATE_GOLDEN") == "1":
        GOLDEN.parent.mkdir(parents=True, exist_ok=True)
        GOLDEN.write_text(text)
    assert text == GOLDEN.read_text()
    assert "latency n/a on a host-timed capture" in text


def test_errors_name_the_file(cli: Cli, tmp_path: Path) -> None:
    missing = cli("compare", str(SAMPLE), str(tmp_path / "nothing.log"))
    assert missing.code != 0 and str(tmp_path / "nothing.log") in missing.err
    assert len(missing.err.strip().splitlines()) == 1
