"""Frames left in columns (``AnnotatedBatch.columnar``) write what the plain path writes: the
Parquet dataset, JSONL and MCAP, compared byte for byte or row for row with the same outputs
made with every frame decoded; on real recordings, the samples with and without a profile, and
generated traffic."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from sniffer.exports import TABLES
from tests.real_recordings import RECORDINGS, TEXT, available
from tests.test_parquet import SAMPLES, table

CAPTURES = Path(__file__).resolve().parents[1] / "captures"
FLOWMETER = Path(__file__).resolve().parent / "data" / "flowmeter.toml"
PUMP = FLOWMETER.with_name("pump.toml")
#: Two of the meter's recordings: one read of HR 13 alone (half a float) in each; the others alike.
METER_RECORDINGS = ["sr_flowmeter_target_20liter_per_min.log", "sr_flowmeter_graph_tool.log"]
PROFILED_RECORDINGS = ["sr_brainchild-io-16do.log", *METER_RECORDINGS]


def _generated(folder: Path, traffic: str, frames: int = 6000) -> Path:
    from benchmarks.bench_memory import benchmark_capture

    return benchmark_capture(folder, frames, traffic)


def _real(folder: Path, name: str) -> Path:
    if not available():
        pytest.skip("needs ../shared/real beside the checkout")
    copy = folder / name
    shutil.copy(TEXT / name, copy)
    return copy


#: A capture (made in a folder), the options it is decoded with, and how many frames at least
#: stay in columns (not vacuous).
CASES = pytest.mark.parametrize(("capture", "setting"), [
    *[(lambda _, sample=sample: CAPTURES / sample, (["--profile", "atv71"], 0)) for sample in SAMPLES],
    *[(lambda _, sample=sample: CAPTURES / sample, ([], 0)) for sample in ("atv71-plc-poll-usb.mcap", "xbt-hmi.mcap")],
    (lambda folder: _generated(folder, "polling"), ([], 5000)),
    (lambda folder: _generated(folder, "coils"), ([], 5000)),
    (lambda folder: _generated(folder, "mixed"), ([], 0)),
    (lambda folder: _generated(folder, "mixed"), (["--profile", "atv71"], 4000)),
    # Coils and discrete inputs a profile names, in columns.
    (lambda folder: _generated(folder, "coils", 2000), (["--profile-file", str(PUMP), "--profile", "pump"], 1500)),
    # Floats in register pairs, every value new, named in columns by the words of both.
    (lambda folder: _generated(folder, "meters", 2000), (["--registers", "f32"], 1500)),
    *[(lambda folder, name=name: _real(folder, name), ([], 0)) for name in RECORDINGS],
    # Real wires read with a profile that names what they carry (wrongly, but every rule applies):
    # the I/O module and two of the flow meter's five recordings, which are much alike.
    *[(lambda folder, name=name: _real(folder, name), (["--profile", profile], 0))
      for name in PROFILED_RECORDINGS for profile in ("atv71", "xbt")],
    # The flow meter's floats, named by a profile of register pairs (and a read of half of one).
    *[(lambda folder, name=name: _real(folder, name), (["--profile-file", str(FLOWMETER), "--profile", "flowmeter"], 0))
      for name in METER_RECORDINGS],
], ids=[*SAMPLES, "usb", "xbt", "polling", "coils", "mixed", "mixed-named", "coils-named", "meters", *RECORDINGS,
        *[f"{name}-{profile}" for name in PROFILED_RECORDINGS for profile in ("atv71", "xbt")],
        *[f"{name}-flowmeter" for name in METER_RECORDINGS]])


@pytest.fixture
def both_ways(monkeypatch: pytest.MonkeyPatch, cli: Callable[..., Any]) -> Callable[..., int]:
    """Runs a command twice, frames in columns wherever they qualify, then none;
    how many frames the first run kept in columns."""
    from decoders.modbus import annotate
    from decoders.modbus.columnar import ColumnarFrames

    def run(columns: list[str], plain: list[str]) -> int:
        in_columns = []
        find = annotate.Annotator._columnar

        def counted(self: annotate.Annotator, batch: Any, *args: Any) -> ColumnarFrames | None:
            found = find(self, batch, *args)
            in_columns.append(0 if found is None else len(found))
            return found

        with monkeypatch.context() as patch:
            patch.setattr(annotate.Annotator, "_columnar", counted)
            assert cli(*columns).code == 0
        with monkeypatch.context() as patch:
            patch.setattr(annotate.Annotator, "annotate_columnar",
                          lambda self, batch, **_: self.annotate_batch(batch))
            assert cli(*plain).code == 0
        return sum(in_columns)

    return run


@CASES
def test_parquet_and_mcap(tmp_path: Path, both_ways: Callable[..., int], capture: Callable[[Path], Path],
                          setting: tuple[list[str], int]) -> None:
    """One export writes both (one decoding a way): the Parquet dataset row for row, the MCAP
    message for message."""
    source, (options, least) = capture(tmp_path), setting
    export = ["export", str(source), "--jobs", "1", "-q", *options]
    assert both_ways([*export, "--parquet", str(tmp_path / "columns"), "--mcap", str(tmp_path / "columns.mcap")],
                     [*export, "--parquet", str(tmp_path / "plain"), "--mcap", str(tmp_path / "plain.mcap")]) >= least
    for name in TABLES:
        assert table(tmp_path / "columns", name) == table(tmp_path / "plain", name), name
    assert _messages(tmp_path / "columns.mcap") == _messages(tmp_path / "plain.mcap")


@CASES
def test_jsonl(tmp_path: Path, both_ways: Callable[..., int], capture: Callable[[Path], Path],
               setting: tuple[list[str], int]) -> None:
    source, (options, least) = capture(tmp_path), setting
    analyze = ["analyze", str(source), "--format", "jsonl", *options, "-o"]
    assert both_ways([*analyze, str(tmp_path / "columns.jsonl")], [*analyze, str(tmp_path / "plain.jsonl")]) >= least
    assert (tmp_path / "columns.jsonl").read_bytes() == (tmp_path / "plain.jsonl").read_bytes()


def _messages(path: Path) -> list[tuple[str, int, bytes]]:
    with path.open("rb") as stream:
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message in make_reader(stream).iter_messages(log_time_order=False)]


@CASES
def test_table(tmp_path: Path, both_ways: Callable[..., int], capture: Callable[[Path], Path],
               setting: tuple[list[str], int]) -> None:
    """The table into a file (a line per frame); with ``--registers`` it reads every decoding,
    those of frames in columns built from their columns."""
    source, (options, least) = capture(tmp_path), setting
    analyze = ["analyze", str(source), *options, "-o"]
    assert both_ways([*analyze, str(tmp_path / "columns.txt")], [*analyze, str(tmp_path / "plain.txt")]) >= least
    assert (tmp_path / "columns.txt").read_bytes() == (tmp_path / "plain.txt").read_bytes()
    typed = [] if "--registers" in options else ["--registers", "s16"]  # one typing of the registers
    registers = ["analyze", str(source), *options, *typed, "--addressing", "4x", "-o"]
    assert both_ways([*registers, str(tmp_path / "r-columns.txt")],
                     [*registers, str(tmp_path / "r-plain.txt")]) >= least
    assert (tmp_path / "r-columns.txt").read_bytes() == (tmp_path / "r-plain.txt").read_bytes()


@CASES
def test_values_and_filtered_outputs(tmp_path: Path, both_ways: Callable[..., int], capture: Callable[[Path], Path],
                                     setting: tuple[list[str], int]) -> None:
    """Outputs that read decodings as objects (``values``), and every output narrowed by a
    filter or a limit, say the same whether frames are decoded in columns or one by one."""
    source, (options, least) = capture(tmp_path), setting
    runs = {
        "values.csv": (["values", str(source), *options, "--format", "csv", "-o"], least),
        "filtered.jsonl": (["analyze", str(source), *options, "--format", "jsonl", "--filter", "role=response",
                            "-o"], least // 4),
        "limited.txt": (["analyze", str(source), *options, "--limit", "700", "-o"], 0),
    }
    for name, (command, at_least) in runs.items():
        assert both_ways([*command, str(tmp_path / f"columns-{name}")],
                         [*command, str(tmp_path / f"plain-{name}")]) >= at_least, name
        assert (tmp_path / f"columns-{name}").read_bytes() == (tmp_path / f"plain-{name}").read_bytes(), name
