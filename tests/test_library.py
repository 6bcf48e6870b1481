"""rtusniff as a library (``sniffer.open_capture``): every table is what ``export --parquet``
writes, for each shipped sample and real recording; statistics and findings are what ``stats``
says; errors are the command line's; the documented examples run."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import sniffer
from tests.conftest import ROOT, CliResult
from tests.real_recordings import TEXT, available

SAMPLES = [*sorted(path.name for path in (ROOT / "captures").glob("*.log")), "atv71-plc-poll.mcap"]
REAL = sorted(path.name for path in TEXT.glob("*.log")) if available() else []


def exported(cli: Callable[..., CliResult], folder: Path, capture: Path, *options: str) -> dict[str, pa.Table]:
    """The tables ``export --parquet`` writes for ``capture``, each as its file reads."""
    assert cli("export", str(capture), "--parquet", str(folder), "-q", *options).code == 0
    tables = {}
    for name in sniffer.TABLES:
        (file,) = folder.glob(f"{name}/bus=*/date=*/*.parquet")  # one day
        tables[name] = pq.read_table(file, partitioning=None)
    return tables


def assert_same_tables(ours: dict[str, pa.Table], theirs: dict[str, pa.Table]) -> None:
    """The same rows in the same order (NaN values alike: by their text), schema and metadata,
    but the command that made them (the library names the ``export`` that decodes alike, without
    ``--parquet``)."""
    for name, table in ours.items():
        written = theirs[name]
        assert table.schema.remove_metadata() == written.schema.remove_metadata(), name
        assert table.num_rows == written.num_rows and repr(table.to_pylist()) == repr(written.to_pylist()), name
        mine, files = dict(table.schema.metadata), dict(written.schema.metadata)
        assert mine.pop(b"rtusniff.command") != files.pop(b"rtusniff.command")
        assert mine == files, name


@pytest.mark.parametrize("sample", SAMPLES)
def test_the_tables_of_each_sample_are_the_export_s(sample: str, tmp_path: Path, cli: Callable[..., CliResult],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # the sources' names as the command line gives them
    capture = Path("captures") / sample
    ours = sniffer.open_capture(capture, profile="atv71").tables()
    assert_same_tables(ours, exported(cli, tmp_path / "plant", capture, "--profile", "atv71"))


@pytest.mark.parametrize("recording", REAL)
def test_the_tables_of_each_real_recording_are_the_export_s(recording: str, tmp_path: Path,
                                                            cli: Callable[..., CliResult]) -> None:
    """The flow meter's floats too (``--registers``), where the meter answers them."""
    options = {"registers": "f32"} if "flowmeter" in recording else {}
    ours = sniffer.open_capture(TEXT / recording, **options).tables()
    argv = ["--registers", "f32"] if options else []
    assert_same_tables(ours, exported(cli, tmp_path / "plant", TEXT / recording, *argv))


def test_statistics_findings_and_frames_are_what_the_commands_say(cli: Callable[..., CliResult],
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    capture = sniffer.open_capture("captures/atv71-plc-poll.log", line="19200 8E1", start="1s")
    stats = json.loads(cli("stats", "captures/atv71-plc-poll.log", "--from", "1s", "--format", "json").out)
    counts = capture.statistics().to_dict()
    assert counts == {key: stats[key] for key in counts}
    assert [finding.to_dict() for finding in capture.findings()] == stats["findings"]
    records = [record for record in cli("analyze", "captures/atv71-plc-poll.log", "--from", "1s", "--format",
                                        "jsonl").jsonl() if record["kind"] == "frame"]
    frames = list(capture.frames())
    assert [(m.frame.index, m.role.value, m.summary) for m in frames] == \
        [(r["index"], r["role"], r["summary"]) for r in records]
    assert capture.table("frames").column("index").to_pylist() == [m.frame.index for m in frames]
    transactions = list(capture.transactions())
    assert [t.request_index for t in transactions] == capture.table("transactions").column("request_index").to_pylist()
    requests = {m.frame.index: m for m in frames if m.role.value == "request"}
    assert all(requests[t.request_index].slave == t.slave for t in transactions if t.request_index in requests)
    assert {t.outcome for t in transactions} == {"answered", "timeout", "exception", "crc_error"}


def test_a_table_with_its_partitions_and_in_pandas(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    capture = sniffer.open_capture("captures/atv71-plc-poll.log", bus="line-3")
    table = capture.table("transactions", partitions=True)
    assert table.column_names[-2:] == ["bus", "date"]
    assert set(table.column("bus").to_pylist()) == {"line-3"} and set(table.column("date").to_pylist()) == {
        "2023-11-14"}
    frame = capture.to_pandas("transactions")
    assert list(frame.columns) == capture.table("transactions").column_names and len(frame) == table.num_rows


@pytest.mark.parametrize(("options", "kind", "said"), [
    ({"lin": "19200 8E1"}, sniffer.ErrorKind.USAGE, "no option 'lin' (the options: around, bus, channel"),
    ({"line": "19200 9Q1"}, sniffer.ErrorKind.USAGE, "--line: line settings '19200 9Q1' are not"),
    ({"profile": "nope"}, sniffer.ErrorKind.USAGE, "unknown profile 'nope'"),
    ({"registers": "f33"}, sniffer.ErrorKind.USAGE, "'f33' is not one of"),
    ({"profile_file": "missing.toml"}, sniffer.ErrorKind.FILE_NOT_FOUND, "missing.toml"),
    ({"bus": ["a", "b"]}, sniffer.ErrorKind.USAGE, "bus takes one value, not 2"),
])
def test_errors_are_the_command_line_s(options: dict[str, Any], kind: sniffer.ErrorKind, said: str,
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    with pytest.raises(sniffer.RtuSniffError, match=re.escape(said)) as raised:
        sniffer.open_capture("captures/atv71-plc-poll.log", **options)
    assert raised.value.kind is kind


def test_a_bad_file_and_a_missing_one(tmp_path: Path) -> None:
    broken = tmp_path / "broken.log"
    broken.write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 0103zz\n")
    with pytest.raises(sniffer.RtuSniffError, match="line 3: bad hex digit 'z'") as raised:
        sniffer.open_capture(broken).table("frames")
    assert raised.value.kind.exit_code == 7 and raised.value.path == str(broken)
    with pytest.raises(sniffer.RtuSniffError, match="no such file") as missing:
        sniffer.open_capture(tmp_path / "none.log")
    assert missing.value.kind is sniffer.ErrorKind.FILE_NOT_FOUND
    with pytest.raises(sniffer.RtuSniffError, match="no table 'frame'; the tables: frames, transactions"):
        sniffer.open_capture(ROOT / "captures" / "atv71-plc-poll.log").table("frame")


def test_a_notebook_s_summary(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    shown = sniffer.open_capture("captures/atv71-plc-poll.log")._repr_html_()
    assert "<th style='text-align:left'>frames</th><td style='text-align:left'>52</td>" in shown
    assert "19200 8E1" in shown and "finding (error)" in shown and "<code>transactions</code>" in shown


def test_polars_missing_is_said() -> None:
    try:
        import polars  # noqa: F401
    except ImportError:
        with pytest.raises(sniffer.RtuSniffError, match="polars is not installed: pip install polars"):
            sniffer.open_capture(ROOT / "captures" / "atv71-plc-poll.log").to_polars("frames")
    else:
        assert sniffer.open_capture(ROOT / "captures" / "atv71-plc-poll.log").to_polars("frames").height == 52


def test_the_documented_examples_run(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Every Python block of docs/api.md, in order, in one namespace, as a notebook runs them;
    a block's ``# prints:`` lines are what it prints. The README's three lines too."""
    monkeypatch.chdir(ROOT)
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert len(blocks) >= 3
    namespace: dict[str, Any] = {}
    for block in blocks:
        if "spark" in block:
            continue  # run by tests/test_spark.py, where a Spark session is
        exec(compile(block, "docs/api.md", "exec"), namespace)
        printed = capsys.readouterr().out
        expected = [line.removeprefix("# prints: ") for line in block.splitlines() if line.startswith("# prints: ")]
        assert printed.splitlines()[:len(expected)] == expected, block
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", readme, re.DOTALL)
    (three_lines,) = [block for block in blocks if "open_capture" in block]
    namespace = {}
    exec(compile(three_lines, "README.md (library)", "exec"), namespace)
    assert namespace["capture"].table("transactions").num_rows == 27


def test_a_capture_decodes_again_but_standard_input_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The commands decode through ``Capture.decode``: the first time from the file opened, again
    by opening it again; standard input is read once."""
    monkeypatch.chdir(ROOT)
    capture = sniffer.open_capture("captures/atv71-plc-poll.log")
    assert len(list(capture.frames())) == len(list(capture.frames())) == capture.statistics().frames == 52
    monkeypatch.setattr("sys.stdin", open(ROOT / "captures" / "atv71-plc-poll.log", encoding="utf-8"))  # noqa: SIM115
    piped = sniffer.open_capture("-")
    assert piped.table("frames").num_rows == 52
    with pytest.raises(sniffer.RtuSniffError, match="a capture read from standard input is decoded once"):
        list(piped.frames())
