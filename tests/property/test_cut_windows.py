"""Hypothesis: ``cut`` of any window of the samples and the real recordings, exact or as a host
read loop delivered them, gives under ``analyze`` the window's frames with the bytes, the times
(to the nanosecond of rounding a character time) and the verdicts (role, flags, the request an
answer pairs with, latency) they had in the whole capture (issue 66: a host cut kept its last
read's time and moved the last frame by up to 11.5 ms; half the cuts lost pairings, retries and
timeouts at their edges). A cut takes the frames of context that make it so, and its note says
where the window is in it."""

from __future__ import annotations

import io
import json
import os
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from functools import cache
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.read_loops import READ_LOOPS
from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from sniffer.cli import main
from sniffer.io.registry import open_writer
from tests import real_recordings
from tests.conftest import ROOT

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "30"))
SCRATCH = Path(tempfile.mkdtemp(prefix="rtusniff-cuts-"))


def _frames(*argv: str) -> list[dict[str, Any]]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(["analyze", *argv, "--format", "jsonl"])
    assert code == 0, err.getvalue()
    return [json.loads(line) for line in out.getvalue().splitlines() if '"kind":"frame"' in line]


@cache
def captures() -> list[tuple[Path, tuple[dict[str, Any], ...]]]:
    """The shipped samples, the real recordings, and each real recording as two host read loops
    deliver it; each with its frames."""
    paths = sorted((ROOT / "captures").glob("*.log")) + sorted((ROOT / "captures").glob("*.mcap"))
    if real_recordings.available():
        for name in real_recordings.RECORDINGS:
            recording = real_recordings.load(name)
            paths.append(real_recordings.TEXT / name)
            for loop in ("usb-16ms", "random-sizes"):
                path = SCRATCH / f"{loop}-{name}"
                writer = open_writer(str(path), CaptureInfo(recording.line, TimingQuality.HOST, ()), "text")
                writer.write_batch(ChunkBatch.from_chunks(READ_LOOPS[loop](recording.chunks, recording.line, 1)))
                writer.close()
                paths.append(path)
    return [(path, tuple(_frames(str(path)))) for path in paths]


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(which=st.integers(0, 999), around=st.integers(0, 10_000), context=st.integers(0, 6))
def test_a_cut_gives_the_window_s_frames_and_times(which: int, around: int, context: int) -> None:
    path, whole = captures()[which % len(captures())]
    index = around % len(whole)
    cut = SCRATCH / f"cut{path.suffix}"
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        assert main(["cut", str(path), "-o", str(cut), "--around", str(index), "--context", str(context),
                     "--force", "-q"]) == 0, err.getvalue()
    window = whole[max(0, index - context) : index + context + 1]
    # The cut's frames keep their numbers: the window is the frames of the window's indexes.
    wanted = {frame["index"] for frame in window}
    got = [frame for frame in _frames(str(cut)) if frame["index"] in wanted]
    assert [f["hex"] for f in got] == [f["hex"] for f in window]
    for mine, theirs in zip(got, window, strict=True):
        assert (mine["index"], mine["role"], mine["flags"], mine["request_index"], mine["latency_s"]) == \
            (theirs["index"], theirs["role"], theirs["flags"], theirs["request_index"], theirs["latency_s"]), \
            (path.name, theirs["index"])
        assert abs(mine["t_ns"] - theirs["t_ns"]) <= 1 and abs(mine["t_end_ns"] - theirs["t_end_ns"]) <= 1, \
            (path.name, theirs["index"])
