"""``report --each``: captures gathered one by one and merged give the report of them read as
one (what each knew of the others aside), and the command around it: a folder, a pool, a bad
file, files named on the rows.

The merge is checked apart from decoding: one capture is decoded once, its annotated batches
are cut into parts, each part gathered by a collector of its own as a separate capture would
be, and the parts merged. Everything must equal one collector given every batch: every chart
bucket, the anomaly counts and rows, the state changes (a part's first state joined to the
last one before it), the value series, the statistics. A real recording of other people's bus
runs through the command.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import re
import shutil
import weakref
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.bench_memory import benchmark_capture
from decoders.anomalies import KINDS
from decoders.capture import CaptureInfo, TimingQuality
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.stats import Statistics
from sniffer.cli import build_parser
from sniffer.commands import report, stats
from sniffer.io.registry import open_reader
from sniffer.many_captures import Tally, each_result
from sniffer.pipeline import Analysis, analyze
from sniffer.profiles_io import profile_book
from sniffer.report.anomalies import CONTEXT
from sniffer.report.collect import Provenance, ReportCollector, SourceFile
from sniffer.sinks import Sink
from tests.property.test_statistics_splits import _slice
from tests.real_recordings import TEXT

CAPTURES = Path(__file__).resolve().parents[1] / "captures"


class _Batches(Sink):
    wants_messages = True

    def __init__(self) -> None:
        self.batches: list[AnnotatedBatch] = []

    def messages(self, batch: AnnotatedBatch) -> None:
        self.batches.append(batch)


def _decoded(path: Path) -> list[AnnotatedBatch]:
    """Every annotated batch of ``path`` (every slave named by the ATV71 profile)."""
    reader = open_reader(str(path))
    assert reader.info.line is not None
    sink = _Batches()
    analyze(reader, str(path), Analysis(reader.info.line, reader.info.timing, profiles=profile_book(["atv71"], [])),
            [sink])
    reader.close()
    return sink.batches


def _gathered(batches: list[AnnotatedBatch], name: str, *, part: bool = False) -> ReportCollector:
    collector = ReportCollector(Provenance([SourceFile(name, 0, "")], "", "", []), part=part)
    collector.start(name, CaptureInfo(LineSettings(19200), TimingQuality.EXACT), LineSettings(19200))
    statistics = Statistics()
    for batch in batches:
        collector.messages(batch)
        statistics.add_batch(batch.messages)
    collector.finish(statistics)
    return collector


def _cut(batches: list[AnnotatedBatch], cuts: list[int]) -> list[list[AnnotatedBatch]]:
    """The frames of ``batches`` in parts that start at the frame indexes ``cuts``."""
    frames = sum(len(batch) for batch in batches)
    parts = []
    for start, stop in itertools.pairwise([0, *cuts, frames]):
        part: list[AnnotatedBatch] = []
        for batch in batches:
            first = batch.messages.frames.first_index
            low, high = max(start - first, 0), min(stop - first, len(batch))
            if low < high:
                part.append(AnnotatedBatch(_slice(batch.messages, low, high), batch.decodings[low:high]))
        parts.append(part)
    return parts


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> list[AnnotatedBatch]:
    return _decoded(benchmark_capture(tmp_path_factory.mktemp("mixed"), 6000, "mixed"))


@pytest.mark.parametrize("cuts", [[2000, 4000], [1, 3000], [1500, 1501, 5999]])
def test_parts_merged_are_the_whole(mixed: list[AnnotatedBatch], cuts: list[int]) -> None:
    whole = _gathered(mixed, "whole")
    merged = ReportCollector(Provenance([], "", "", []))
    for number, part in enumerate(_cut(mixed, cuts)):
        merged.merge(_gathered(part, f"part{number}", part=True).portable())
    timeline, expected = merged.timeline, whole.timeline
    assert (timeline.origin_ns, timeline.width_ns, timeline.used) == (expected.origin_ns, expected.width_ns,
                                                                      expected.used)
    assert timeline.series.keys() == expected.series.keys()
    for name, series in expected.series.items():
        np.testing.assert_allclose(timeline.series[name].values, series.values, rtol=1e-12, equal_nan=True,
                                   err_msg=name)
    assert merged.anomalies.counts == whole.anomalies.counts
    near_a_cut = {index for cut in cuts for index in range(cut - CONTEXT, cut + CONTEXT)}
    for kind in KINDS:
        mine, theirs = merged.anomalies.kept[kind], whole.anomalies.kept[kind]
        assert [(a.row.index, a.with_context) for a in mine] == [(a.row.index, a.with_context) for a in theirs]
        for a, b in zip(mine, theirs, strict=True):
            assert a.row.capture.startswith("part") and a.row.summary == b.row.summary
            if a.with_context and a.row.index not in near_a_cut:
                assert [r.index for r in a.before + a.after] == [r.index for r in b.before + b.after]
    changes = [(c.index, c.slave, c.code, c.before, c.after) for c in merged.values.changes]
    assert changes == [(c.index, c.slave, c.code, c.before, c.after) for c in whole.values.changes]
    assert merged.values.changes_total == whole.values.changes_total and changes
    assert merged.values.series == whole.values.series
    assert merged.slaves == whole.slaves
    counts = merged.statistics.to_dict(), whole.statistics.to_dict()
    for key in ("duration_s", "bus_load", "per_slave_function"):  # poll periods over a cut are not counted
        counts[0].pop(key), counts[1].pop(key)
    assert counts[0] == counts[1]


def _copies(folder: Path, names: list[str]) -> None:
    folder.mkdir()
    for name in names:
        shutil.copy(CAPTURES / name, folder / name)


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_folder_with_a_bad_file(tmp_path: Path, cli: Callable[..., Any], jobs: str) -> None:
    """One error line for the damaged capture, the report of the others (their frames, their
    anomalies named with their file), exit 15; each capture's frame count as its own stats."""
    folder = tmp_path / "site"
    names = ["atv71-plc-poll.mcap", "atv312-setup.log", "xbt-hmi.log"]
    _copies(folder, names)
    (folder / "broken.log").write_text("# rtu-capture v1\n# line: 19200 8N1\n1.0 zz\n")
    result = cli("report", "--each", str(folder), "-o", str(tmp_path / "r.html"), "--jobs", jobs)
    assert result.code == 15
    errors = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "broken.log" in errors[0] and "1 of 4 captures failed" in result.err
    frames = sum(json.loads(cli("stats", str(folder / name), "--format", "json").out)["frames"] for name in names)
    assert f"report of {frames:,} frames, 3 captures" in result.err
    html = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert "each read on its own and merged (--each)" in html
    for name in names:
        assert str(folder / name) in html
    labelled = re.findall(r"<p class=\"muted\">#\d+ of ([^ ]+) at ", html)
    assert labelled and set(labelled) <= {str(folder / name) for name in names}
    assert "rtusniff analyze FILE --around INDEX --context 5" in html


def test_no_report_when_every_capture_fails(tmp_path: Path, cli: Callable[..., Any]) -> None:
    folder = tmp_path / "site"
    folder.mkdir()
    (folder / "broken.log").write_text("# rtu-capture v1\n# line: 19200 8N1\n1.0 zz\n")
    result = cli("report", "--each", str(folder), "-o", str(tmp_path / "r.md"))
    assert result.code == 15 and "1 of 1 captures failed" in result.err
    assert not (tmp_path / "r.md").exists()


def test_markdown_names_each_example_and_what_went_unnamed(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Slave 2 identifies itself in one capture only: the report says so and gives the option."""
    folder = tmp_path / "site"
    _copies(folder, ["atv71-plc-poll.log", "xbt-hmi.log"])
    result = cli("report", "--each", str(folder), "-o", str(tmp_path / "r.md"), "--jobs", "1")
    assert result.code == 0, result.err
    text = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert "(FILE: the file an example names)" in text
    assert re.search(r"^#\d+ of .+atv71-plc-poll\.log at ", text, re.M)
    line = next(line for line in text.splitlines() if line.startswith("| identification |"))
    assert "2 (in 1 of 2 captures)" in line and "--profile 2=atv71" in line


@pytest.mark.skipif(not TEXT.is_dir(), reason="../shared/real is not here")
def test_real_recordings_as_a_folder(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Other people's recordings, each its own capture: the merged frame count is theirs summed."""
    files = sorted(map(str, TEXT.glob("*.log")))
    result = cli("report", "--each", str(TEXT), "-o", str(tmp_path / "r.md"), "--jobs", "2")
    assert result.code == 0, result.err
    frames = sum(json.loads(cli("stats", path, "--format", "json").out)["frames"] for path in files)
    assert f"report of {frames:,} frames, {len(files)} captures" in result.err
    text = (tmp_path / "r.md").read_text(encoding="utf-8")
    assert all(f"| file | {path}: " in text for path in files)  # more than MANY_FILES: one line each


@pytest.mark.parametrize("command", ["report", "stats"])
def test_no_result_outlives_its_turn(tmp_path: Path, command: str) -> None:
    """Memory stays flat over thousands of captures: ``--each`` keeps nothing of a capture's result
    once the command has it (a report's part, a capture's statistics: megabytes each). When the
    outcomes kept them for the exit code, report reached 680 MB at 160 captures, stats 327 MB at 120."""
    folder = tmp_path / "site"
    _copies(folder, ["atv71-plc-poll.mcap", "xbt-hmi.mcap"])
    paths = [str(path) for path in sorted(folder.iterdir())]
    args = build_parser().parse_args([command, "--each", str(folder), "-o", str(tmp_path / "out"), "--jobs", "1"])
    args.command_line = [command]
    one = argparse.Namespace(**{**vars(args), "each": False, "quiet": True})
    worker = report._gathered_one if command == "report" else stats._counted
    tally = Tally(3)
    alive = [weakref.ref(result) for result in each_result([*paths, str(tmp_path / "missing.log")], worker, one, 1,
                                                           tally, show=False)]
    gc.collect()
    assert len(alive) == 2 and all(ref() is None for ref in alive)
    assert (tally.done, tally.failed) == (2, 1)
    if command == "report":
        merged = report._gathered_each(args, paths, Tally(2))
        assert merged is not None and len(merged.provenance.files) == 2
