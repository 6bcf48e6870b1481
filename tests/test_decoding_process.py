"""Decoding in a second process (``--jobs 2``): the same output as one process, failures said
the same way, the child never left behind."""

from __future__ import annotations

import os
import re
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.pipeline import Decoder
from sniffer.decoding_process import RECEIVED_AHEAD, ChildDecoding, decode_here
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.registry import open_reader
from tests.conftest import SAMPLE_LOG, SAMPLE_MCAP, CliResult

Cli = Callable[..., CliResult]
CAPTURES = Path(__file__).parent.parent / "captures"
SAMPLES = sorted(CAPTURES.glob("*.log"))
LINE = LineSettings.parse("19200 8E1")


def mcap_messages(path: Path) -> list[tuple[str, int, int, bytes]]:
    with path.open("rb") as f:
        return [
            (c.topic, m.sequence, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)
        ]


@pytest.mark.parametrize("sample", SAMPLES, ids=[s.stem for s in SAMPLES])
def test_two_processes_give_what_one_gives(cli: Cli, tmp_path: Path, sample: Path) -> None:
    outputs: dict[str, list[Any]] = {}
    for jobs in ("1", "2"):
        mcap = tmp_path / f"{jobs}.mcap"
        runs = [
            cli("analyze", str(sample), "--format", "jsonl", "--jobs", jobs),
            cli("analyze", str(sample), "--filter", "role=response", "--jobs", jobs),
            cli("export", str(sample), "--mcap", str(mcap), "--jobs", jobs),
        ]
        assert [run.code for run in runs] == [0] * len(runs), [run.err for run in runs]
        # The export's report names its own output file: the same but for the name.
        outputs[jobs] = [(run.out, run.err.replace(str(mcap), "OUT")) for run in runs] + mcap_messages(mcap)
    assert outputs["1"] == outputs["2"]


def test_an_export_with_every_output_in_two_processes(cli: Cli, tmp_path: Path) -> None:
    """Rerun's SDK starts threads: it is started after the fork, and the recording is complete."""
    os.environ.setdefault("CI", "1")
    rrd, pcap = tmp_path / "out.rrd", tmp_path / "out.pcap"
    result = cli("export", str(SAMPLE_LOG), "--rrd", str(rrd), "--pcap", str(pcap), "--jobs", "2")
    assert result.code == 0, result.err
    single = cli("export", str(SAMPLE_LOG), "--pcap", str(tmp_path / "one.pcap"), "--jobs", "1")
    assert single.code == 0 and (tmp_path / "one.pcap").read_bytes() == pcap.read_bytes()
    assert rrd.stat().st_size > 10_000


def cut_short(source: Path, target: Path) -> None:
    """``source`` up to its Data End record, as a recording killed after its last flush is."""
    data, offset = source.read_bytes(), 8
    while data[offset] != 0x0F:  # Data End
        offset += 9 + struct.unpack_from("<Q", data, offset + 1)[0]
    target.write_bytes(data[:offset])


def test_the_readers_warnings_come_back(cli: Cli, tmp_path: Path) -> None:
    recording = tmp_path / "killed.mcap"
    cut_short(SAMPLE_MCAP, recording)
    results = [cli("analyze", str(recording), "--format", "jsonl", "--jobs", jobs) for jobs in ("1", "2")]
    assert results[0].code == results[1].code == 0
    assert "recording cut short" in results[0].err and results[0].err == results[1].err
    assert results[0].out == results[1].out


class Reader:
    """A capture reader that yields the sample's batches, then does what the test asks."""

    def __init__(self, then: Callable[[], None] | None = None, *, repeat: int = 1) -> None:
        sample = open_reader(str(SAMPLE_LOG))
        self._batches = list(sample.batches())
        sample.close()
        self.info = CaptureInfo(line=LINE, timing=TimingQuality.EXACT)
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        self._then = then
        self._repeat = repeat

    def batches(self) -> Iterator[ChunkBatch]:
        for _ in range(self._repeat):
            yield from self._batches
        self.warnings.append("said by the child")
        if self._then is not None:
            self._then()

    def close(self) -> None:
        pass


def steps_in_child(reader: Reader) -> tuple[list[int], ChildDecoding]:
    child = ChildDecoding(reader, Decoder(LINE, TimingQuality.EXACT), with_chunks=True)
    frames: list[int] = []
    try:
        for step in child:
            frames.append(sum(len(batch) for batch in step.batches))
    finally:
        child.close()
    return frames, child


def assert_reaped(child: ChildDecoding) -> None:
    with pytest.raises(ChildProcessError):
        os.waitpid(child.pid, os.WNOHANG)


def test_the_child_sends_every_step_then_the_warnings() -> None:
    reader = Reader()
    frames, child = steps_in_child(reader)
    here = [
        sum(len(batch) for batch in step.batches) for step in decode_here(Reader(), Decoder(LINE, TimingQuality.EXACT))
    ]
    assert frames == here and sum(frames) == 52
    assert reader.warnings == ["said by the child"]
    assert_reaped(child)


def test_the_first_batch_goes_as_read_and_the_rest_joined() -> None:
    """The parent starts on the first batch while the child joins the next ones."""
    read = Reader(repeat=3)
    as_read = [len(batch) for batch in read.batches()]
    assert len(as_read) >= 3
    steps = decode_here(Reader(repeat=3), Decoder(LINE, TimingQuality.EXACT), join=(10**6, 10**9))
    chunks = [len(step.chunks) for step in steps if step.chunks is not None]
    assert chunks == [as_read[0], sum(as_read[1:])]


def fail_with_bad_data() -> None:
    raise RtuSniffError(ErrorKind.BAD_DATA, "bad hex digit 'Z'", path="c.log", location="line 9")


def test_an_error_in_the_child_is_raised_as_it_was() -> None:
    reader = Reader(fail_with_bad_data)
    with pytest.raises(RtuSniffError) as raised:
        steps_in_child(reader)
    assert raised.value.kind is ErrorKind.BAD_DATA and str(raised.value) == "c.log:line 9: bad hex digit 'Z'"
    assert "in the decoding process" in raised.value.__notes__[0]
    assert reader.warnings == ["said by the child"]


def fail_to_read() -> None:
    raise OSError(5, "Input/output error")


def test_a_read_error_in_the_child_is_raised_not_taken_for_a_broken_pipe() -> None:
    with pytest.raises(OSError, match="Input/output error"):
        steps_in_child(Reader(fail_to_read))


class UnpicklableError(Exception):
    def __init__(self) -> None:
        super().__init__("cannot travel")
        self.handle = lambda: None


def fail_unpicklably() -> None:
    raise UnpicklableError


def test_an_error_that_does_not_pickle_comes_back_as_its_text() -> None:
    with pytest.raises(RuntimeError, match="UnpicklableError: cannot travel"):
        steps_in_child(Reader(fail_unpicklably))


def refuse_to_load() -> None:
    raise ValueError("this step does not load")


class Unloadable:
    """Pickles, but fails to unpickle (in the parent)."""

    def __reduce__(self) -> tuple[Callable[[], None], tuple[()]]:
        return refuse_to_load, ()


def test_a_step_that_does_not_unpickle_is_raised_not_waited_for() -> None:
    child = ChildDecoding(Reader(), Decoder(LINE, TimingQuality.EXACT), with_chunks=False,
                          prepare=lambda batch: Unloadable())
    try:
        with pytest.raises(ValueError, match="this step does not load"):
            list(child)
    finally:
        child.close()
    assert_reaped(child)
    assert not receiving_threads()


def test_a_child_that_dies_is_one_error() -> None:
    with pytest.raises(RtuSniffError, match=r"ended without a word \(killed by SIGKILL\)") as raised:
        steps_in_child(Reader(lambda: os.kill(os.getpid(), signal.SIGKILL)))
    assert raised.value.kind is ErrorKind.RUNTIME


def receiving_threads() -> list[threading.Thread]:
    return [thread for thread in threading.enumerate() if thread.name == "rtusniff-receive"]


def test_stopping_early_stops_the_child_and_the_receiving_thread() -> None:
    child = ChildDecoding(Reader(repeat=10**6), Decoder(LINE, TimingQuality.EXACT), with_chunks=False)
    pipe = child._receive
    try:
        first = next(iter(child))
        assert first.chunks is None and first.batches
    finally:
        child.close()
    assert_reaped(child)
    assert not receiving_threads()
    with pytest.raises(OSError):
        os.fstat(pipe)  # the pipe closed with them
    child.close()  # once: nothing more to close


def test_steps_are_received_ahead_while_the_parent_works() -> None:
    """A thread takes the next steps off the pipe while the parent is busy with one."""
    child = ChildDecoding(Reader(repeat=10**6), Decoder(LINE, TimingQuality.EXACT), with_chunks=False)
    try:
        next(iter(child))
        deadline = time.monotonic() + 30
        while child._received.qsize() < RECEIVED_AHEAD and time.monotonic() < deadline:
            time.sleep(0.01)
        assert child._received.qsize() == RECEIVED_AHEAD
    finally:
        child.close()
    assert not receiving_threads()


def test_ctrl_c_leaves_a_valid_export_and_no_child(tmp_path: Path) -> None:
    """Ctrl-C reaches the whole process group: the child ignores it, the parent stops it and
    closes the export."""
    output = tmp_path / "interrupted.mcap"
    command = [sys.executable, "-m", "sniffer", "export", "-", "--mcap", str(output), "--jobs", "2"]
    # An ignored SIGINT stays ignored across exec (a background shell job ignores it): handled here.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        export = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
            env={**os.environ, "CI": "1"},
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    assert export.stdin is not None
    export.stdin.write(SAMPLE_LOG.read_text())  # no end of input: the child waits for more
    export.stdin.flush()
    time.sleep(3.0)  # the interpreter starts, forks, and both wait
    os.killpg(export.pid, signal.SIGINT)
    _, err = export.communicate(timeout=60)
    assert export.returncode == 130, err
    with pytest.raises(ProcessLookupError):
        os.killpg(export.pid, 0)  # nobody left in the group: the child is gone too
    assert_kept_incomplete(output, err)


def assert_kept_incomplete(output: Path, err: str) -> None:
    """An interrupted export: nothing under its own name, the part exported kept under a name and
    in a metadata record that say incomplete, and a line saying where and how many frames."""
    kept = output.with_name(f"{output.stem}.incomplete{output.suffix}")
    assert not output.exists() and kept.exists()
    frames = int(re.search(rf"interrupted: {re.escape(str(output))} kept incomplete as {re.escape(str(kept))} "
                           r"\(([\d,]+) frames\)\n", err)[1].replace(",", ""))  # type: ignore[index]
    assert err.endswith("interrupted\n")
    with kept.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert summary is not None and "/modbus/frames" in {c.topic for c in summary.channels.values()}
    assert metadata["rtusniff.incomplete"] == {"reason": "interrupted", "frames": str(frames)}
    with kept.open("rb") as f:
        written = sum(1 for _ in make_reader(f).iter_messages(topics=["/modbus/frames"]))
    assert written == frames


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_kill_int_stops_an_export_a_script_started_in_the_background(tmp_path: Path, jobs: str) -> None:
    """A shell script's background job starts with SIGINT ignored; ``kill -INT`` ran such an
    export to the end with exit 0. It stops it as Ctrl-C does: exit 130, the export kept, incomplete."""
    output = tmp_path / "background.mcap"
    command = [sys.executable, "-m", "sniffer", "export", "-", "--mcap", str(output), "--jobs", jobs]
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # inherited across exec, as a shell does it
    try:
        export = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                  start_new_session=True, env={**os.environ, "CI": "1"})
    finally:
        signal.signal(signal.SIGINT, previous)
    assert export.stdin is not None
    export.stdin.write(SAMPLE_LOG.read_text())  # no end of input: it waits for more
    export.stdin.flush()
    time.sleep(3.0)
    export.send_signal(signal.SIGINT)
    _, err = export.communicate(timeout=60)
    assert export.returncode == 130, err
    assert_kept_incomplete(output, err)
