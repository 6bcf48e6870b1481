"""Replay pacing (``--speed``), following a growing file (``--follow``), viewer addresses."""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import RtuSniffError
from sniffer.exports.streams import parse_address, rerun_address
from sniffer.io import following
from sniffer.io.following import QUIET, FollowingReader, GrowingFile
from sniffer.io.mcap_native import McapCaptureReader, McapCaptureWriter
from sniffer.io.pacing import SLICE_S, PacedReader, parse_speed


class _ListReader:
    def __init__(self, batches: list[ChunkBatch]) -> None:
        self._batches = batches
        self.info = CaptureInfo(LineSettings.parse("19200 8N1"), TimingQuality.HOST)
        self.late_notes: list[str] = []
        self.warnings: list[str] = []

    def batches(self):  # type: ignore[no-untyped-def]
        yield from self._batches

    def last_time_ns(self) -> int | None:
        return None

    def close(self) -> None:
        pass


class _FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds > 0
        self.now += seconds


def _batch(times_ms: list[int]) -> ChunkBatch:
    return ChunkBatch.from_chunks([Chunk(1_700_000_000_000_000_000 + t * 1_000_000, bytes([k % 256]))
                                   for k, t in enumerate(times_ms)])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 20_000), min_size=1, max_size=200), st.sampled_from([0.5, 1.0, 4.0, 10.0]),
       st.integers(1, 5))
def test_a_paced_replay_hands_on_every_chunk_when_its_time_comes(gaps: list[int], speed: float, parts: int) -> None:
    """Every chunk once, in order, however the capture is cut into batches; no slice comes
    before its time, none later than when it was handed on, and each spans at most a slice."""
    times = np.cumsum(gaps).tolist()
    whole = _batch(times)
    cuts = sorted({0, len(times), *np.linspace(0, len(times), parts + 1).astype(int).tolist()})
    clock = _FakeClock()
    paced = PacedReader(_ListReader([whole.slice(a, b) for a, b in itertools.pairwise(cuts) if b > a]),
                        speed, clock=clock, sleep=clock.sleep)
    start, t0 = clock.now, int(whole.t_end_ns[0])
    handed = []
    for piece in paced.batches():
        due = start + (int(piece.t_end_ns[-1]) - t0) / 1e9 / speed
        assert clock.now == pytest.approx(max(due, clock.now)) and clock.now >= due - 1e-9
        assert (int(piece.t_end_ns[-1]) - int(piece.t_end_ns[0])) / 1e9 / speed <= SLICE_S + 1e-9
        handed.append(piece)
    assert ChunkBatch.concat(handed).data == whole.data
    assert clock.now - start == pytest.approx((times[-1] - times[0]) / 1e3 / speed)


@pytest.mark.parametrize(("text", "speed"), [("1", 1.0), ("10", 10.0), ("0.5", 0.5), ("max", None), ("MAX", None)])
def test_speed_values(text: str, speed: float | None) -> None:
    assert parse_speed(text) == speed


@pytest.mark.parametrize("text", ["0", "-1", "fast", "inf", "nan", ""])
def test_wrong_speeds(text: str) -> None:
    with pytest.raises(RtuSniffError, match="--speed"):
        parse_speed(text)


@pytest.mark.parametrize(("text", "address"), [
    ("8765", ("127.0.0.1", 8765)), ("0", ("127.0.0.1", 0)), ("0.0.0.0:9000", ("0.0.0.0", 9000)),
    ("[::1]:8765", ("::1", 8765)), ("myhost:1", ("myhost", 1)),
])
def test_foxglove_addresses(text: str, address: tuple[str, int]) -> None:
    assert parse_address(text) == address


@pytest.mark.parametrize(("text", "url"), [
    ("9876", "rerun+http://127.0.0.1:9876/proxy"), ("box:9877", "rerun+http://box:9877/proxy"),
    ("rerun+http://10.0.0.2:9876/proxy", "rerun+http://10.0.0.2:9876/proxy"),
])
def test_rerun_addresses(text: str, url: str) -> None:
    assert rerun_address(text) == url


@pytest.mark.parametrize("text", ["nowhere", "70000", "host:", ":"])
def test_wrong_viewer_addresses(text: str) -> None:
    with pytest.raises(RtuSniffError):
        rerun_address(text)
    if not text.startswith("host"):
        with pytest.raises(RtuSniffError):
            parse_address(text)


def test_a_growing_file_waits_for_what_is_still_to_be_written(tmp_path: Path) -> None:
    path = tmp_path / "growing.log"
    path.write_bytes(b"first line\nsec")
    growing = GrowingFile(str(path), poll_s=0.01)

    def write_later() -> None:
        time.sleep(0.2)
        with open(path, "ab") as f:
            f.write(b"ond line\n1234")

    writer = threading.Thread(target=write_later)
    writer.start()
    try:
        assert growing.readline() == b"first line\n"
        assert not growing.caught_up()
        assert growing.readline() == b"second line\n"  # waited for its end
        assert growing.read(4) == b"1234" and growing.caught_up()
        following.STOP.set()
        assert growing.read(4) == b""  # stopped: the end of the file is the end
        assert growing.readline() == b""
    finally:
        following.STOP.clear()
        writer.join()
        growing.close()


def test_a_native_recording_is_read_as_it_is_written(tmp_path: Path) -> None:
    """Blocks come as the writer flushes them, the quiet spells are said once each, and the
    reading ends with the file's closing record: everything written, in order."""
    path = tmp_path / "rec.mcap"
    info = CaptureInfo(LineSettings.parse("19200 8N1"), TimingQuality.HOST)
    writer = McapCaptureWriter(str(path), info)
    blocks = [_batch([k * 1000 + t for t in range(5)]) for k in range(4)]
    reader = FollowingReader(McapCaptureReader(str(path), follow=True), quiet_after_s=0.3)
    got: list[ChunkBatch] = []
    done = threading.Event()

    def read() -> None:
        got.extend(reader.batches())
        done.set()

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    try:
        for count, block in enumerate(blocks, 1):
            writer.write_batch(block)
            writer.flush()
            deadline = time.monotonic() + 10
            while sum(len(b) for b in got) < sum(len(b) for b in blocks[:count]):
                assert time.monotonic() < deadline, "a flushed block was not read"
                time.sleep(0.01)
        time.sleep(0.6)  # a quiet spell: said once
        assert not done.is_set()
        writer.close()
        assert done.wait(10)
    finally:
        reader.close()
    data = [b for b in got if len(b)]
    assert ChunkBatch.concat(data).data == ChunkBatch.concat(blocks).data
    assert sum(b is QUIET for b in got) == 1


def test_a_live_rerun_sender_skips_rounds_it_cannot_keep_up_with() -> None:
    """The decoding never waits for the SDK: rounds beyond MAX_PENDING are skipped and counted;
    what was handed over is sent in order, and close waits for it."""
    from sniffer.exports.rerun_live import MAX_PENDING, LiveSender

    sent: list[int] = []
    release = threading.Event()

    def send(items: list[int]) -> None:
        release.wait(10)
        sent.extend(items)

    sender = LiveSender(send)
    for round_number in range(10):
        sender.submit([round_number], rows=3)
    assert sender.skipped_rows == 3 * (10 - MAX_PENDING)
    release.set()
    sender.close()
    assert sent == list(range(MAX_PENDING))


def test_the_names_of_a_rotation(tmp_path: Path) -> None:
    from sniffer.io.following import followed_path
    from sniffer.io.rotation import next_rotated

    assert next_rotated(str(tmp_path / "site-0009.mcap")) == str(tmp_path / "site-0010.mcap")
    assert next_rotated(str(tmp_path / "site.mcap")) is None
    assert followed_path(str(tmp_path / "site.mcap")) == str(tmp_path / "site.mcap")  # none yet: as named
    for number in (1, 2, 10):
        (tmp_path / f"site-{number:04d}.mcap").write_bytes(b"")
    assert followed_path(str(tmp_path / "site.mcap")) == str(tmp_path / "site-0010.mcap")
