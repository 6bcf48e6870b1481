"""Many captures at once (``--each``): statistics merged exactly, one bad file one error line,
a whole folder exported into one Parquet dataset, in a pool of processes or in one."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from decoders.capture import TimingQuality
from decoders.pipeline import Decoder
from decoders.stats import Statistics
from sniffer.io.registry import open_reader
from tests.real_recordings import REAL

CAPTURES = Path(__file__).resolve().parents[1] / "captures"


def statistics_of(*paths: Path) -> Statistics:
    """One statistics counting the frames of every capture, each decoded on its own."""
    statistics = Statistics()
    for path in paths:
        reader = open_reader(str(path))
        assert reader.info.line is not None
        decoder = Decoder(reader.info.line, TimingQuality.EXACT)
        for batch in reader.batches():
            for messages in decoder.feed(batch):
                statistics.add_batch(messages)
        for messages in decoder.flush():
            statistics.add_batch(messages)
        reader.close()
    return statistics


def test_merged_statistics_are_the_statistics_of_both() -> None:
    """Two captures of different slaves: merging their statistics gives what counting both
    captures' frames into one gives, bin for bin (only the duration is the sum of theirs)."""
    a, b = statistics_of(CAPTURES / "atv71-plc-poll.log"), statistics_of(CAPTURES / "xbt-hmi.log")
    both = statistics_of(CAPTURES / "atv71-plc-poll.log", CAPTURES / "xbt-hmi.log")
    merged = Statistics()
    merged.merge(a.portable())
    merged.merge(b.portable())
    assert merged.duration_ns == a.duration_ns + b.duration_ns
    mine, theirs = merged.to_dict(), both.to_dict()
    for key in ("duration_s", "bus_load"):
        mine.pop(key), theirs.pop(key)
    assert mine == theirs
    for key, stats in both.per_function.items():
        assert np.array_equal(merged.per_function[key].latency.counts, stats.latency.counts)
        assert np.array_equal(merged.per_function[key].poll_period.counts, stats.poll_period.counts)


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_stats_of_a_folder(tmp_path: Path, cli: Callable[..., Any], jobs: str) -> None:
    """A folder of captures and a damaged one: one error line for it, the merged table of the rest
    (as many frames as their own stats), exit 15."""
    folder = tmp_path / "site"
    folder.mkdir()
    for name in ("atv71-plc-poll.mcap", "xbt-hmi.mcap", "atv312-setup.log"):
        shutil.copy(CAPTURES / name, folder / name)
    (folder / "broken.log").write_text("# rtu-capture v1\n# line: 19200 8N1\n1.0 zz\n")
    (folder / "notes.txt.bak").write_text("not a capture")
    result = cli("stats", "--each", str(folder), "--format", "json", "--jobs", jobs)
    assert result.code == 15
    errors = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "broken.log" in errors[0]
    assert "1 of 4 captures failed" in result.err
    merged = json.loads(result.out)
    alone = [json.loads(cli("stats", str(folder / name), "--format", "json").out)
             for name in ("atv71-plc-poll.mcap", "xbt-hmi.mcap", "atv312-setup.log")]
    assert merged["frames"] == sum(s["frames"] for s in alone) and merged["source"] == "3 of 4 captures"
    assert merged["crc_errors"] == sum(s["crc_errors"] for s in alone)
    assert merged["duration_s"] == pytest.approx(sum(s["duration_s"] for s in alone))
    by_source = {Path(c["source"]).name: (c["line"], c["timing"]) for c in merged["captures"]}
    assert by_source == {name: (s["line"], s["timing"]) for name, s in
                         zip(("atv71-plc-poll.mcap", "xbt-hmi.mcap", "atv312-setup.log"), alone, strict=True)}


def test_stats_of_a_folder_says_each_capture_s_line(cli: Callable[..., Any]) -> None:
    """The real recordings: five flow-meter captures at 9600 8N1 and one I/O module at 19200 8E1.
    The table's heading said the first capture's ``19200 8E1`` for all six; it says ``mixed`` and
    lists each setting with its captures, the JSON document each capture."""
    folder = REAL / "sigrok-cli-text"
    table = cli("stats", "--each", str(folder), "--jobs", "1")
    assert table.code == 0, table.err
    heading = [line for line in table.out.splitlines() if line.startswith("#")][:3]
    assert heading[0].startswith("# 6 of 6 captures  line mixed  timing exact")
    assert "line 19200 8E1, timing exact: 1 capture (" in heading[1] and "brainchild" in heading[1]
    assert "line 9600 8N1, timing exact: 5 captures (" in heading[2] and heading[2].endswith(", …)")
    document = json.loads(cli("stats", "--each", str(folder), "--format", "json", "--jobs", "1").out)
    assert document["line"] == "mixed" and document["timing"] == "exact"
    assert sorted(c["line"] for c in document["captures"]) == ["19200 8E1"] + ["9600 8N1"] * 5
    same = json.loads(cli("stats", "--each", str(folder / "sr_flowmeter_graph_tool.log"),
                          str(folder / "sr_flowmeter_target0_val0.log"), "--format", "json").out)
    assert same["line"] == "9600 8N1" and len(same["captures"]) == 2


def test_a_folder_into_one_dataset(tmp_path: Path, cli: Callable[..., Any]) -> None:
    duckdb = pytest.importorskip("duckdb")
    folder = tmp_path / "site"
    folder.mkdir()
    names = ["atv71-plc-poll.mcap", "xbt-hmi.mcap", "atv312-setup.mcap", "nord-uss.mcap"]
    for name in names:
        shutil.copy(CAPTURES / name, folder / name)
    result = cli("export", "--each", str(folder), "--parquet", str(tmp_path / "d"), "--jobs", "2")
    assert result.code == 0 and "added 20 files" in result.err and "of 4 captures" in result.err
    counts = dict(duckdb.sql(f"SELECT bus, count(*) FROM read_parquet('{tmp_path}/d/frames/**/*.parquet', "
                             "hive_partitioning = true) GROUP BY bus").fetchall())
    assert counts == {Path(name).stem: json.loads(cli("stats", str(folder / name), "--format", "json").out)["frames"]
                      for name in names}


@pytest.mark.parametrize(("args", "said"), [
    (["export", "--each", "captures", "--mcap", "x.mcap"], "--each exports many captures into one --parquet"),
    (["stats", "--each", "captures", "--follow"], "--follow follows one capture"),
    (["stats", "--each", "captures", "--jobs", "0"], "--jobs 0"),
    (["stats", "--each", "-"], "--each reads files"),
])
def test_each_option_errors(cli: Callable[..., Any], args: list[str], said: str, monkeypatch: pytest.MonkeyPatch
                            ) -> None:
    monkeypatch.chdir(CAPTURES.parent)
    result = cli(*args)
    assert result.code == 2 and said in result.err and result.err.count("\n") == 1
