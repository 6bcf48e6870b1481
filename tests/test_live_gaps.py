"""A live capture whose decoding falls behind: skipped reads are said (a ``gap`` record, the
summary, standard error), and decoding starts again after them instead of splicing bytes that
were never adjacent on the wire into invented noise and CRC errors; a read stamped but not yet
queued holds the decoder's clock back."""

from __future__ import annotations

import io
import json
import queue
import threading

import pytest

from decoders.capture import CaptureInfo, Chunk, TimingQuality
from decoders.line import LineSettings
from sniffer.live_capture import CaptureOptions, _queue, _Session, _Shared, _Skipped
from sniffer.serial_source import PortStatus

REQUEST = bytes.fromhex("02030C1E0004276C")
RESPONSE = bytes.fromhex("0203080028025801F4000052B0")
T0 = 1_700_000_000_000_000_000
MS = 1_000_000


class Clock:
    """A serial source's clock: now, and where a read not yet queued began (``in_flight``)."""

    def __init__(self) -> None:
        self.now = T0
        self.in_flight: int | None = None

    def now_ns(self) -> int:
        return self.now

    def heard_until_ns(self) -> int:
        return self.now if self.in_flight is None else min(self.now, self.in_flight)


def _session(out: io.StringIO, shared: _Shared, response_timeout_ns: int | None = None) -> _Session:
    options = CaptureOptions("/dev/ttyTEST", LineSettings.parse("19200 8E1"), None, None, "jsonl", None,
                             response_timeout_ns, None)
    session = _Session(options, PortStatus(None, None, False), None, shared, out)
    session.delivery.start("/dev/ttyTEST", CaptureInfo(options.line, TimingQuality.HOST), options.line)
    return session


def test_a_full_queue_marks_what_it_dropped() -> None:
    shared = _Shared(threading.Event(), queue.Queue(2))
    skipped = _Skipped()
    for k in range(5):
        skipped = _queue(shared, Chunk(T0 + k, bytes([k]) * 3), skipped)
    assert shared.behind_reads == 3 and (skipped.reads, skipped.size) == (3, 9)
    shared.reads.get_nowait()
    shared.reads.get_nowait()
    skipped = _queue(shared, Chunk(T0 + 9, b"\x09"), skipped)  # room again: the mark, then the read
    mark, after = shared.reads.get_nowait(), shared.reads.get_nowait()
    assert isinstance(mark, _Skipped) and (mark.reads, mark.size, mark.t_ns) == (3, 9, T0 + 9)
    assert isinstance(after, Chunk) and after.data == b"\x09" and skipped.reads == 0


def test_decoding_restarts_at_a_gap() -> None:
    out, clock = io.StringIO(), Clock()
    shared = _Shared(threading.Event(), queue.Queue())
    session = _session(out, shared)
    exchanges = []
    t = T0
    for _ in range(3):
        exchanges += [Chunk(t, REQUEST), Chunk(t + 12 * MS, RESPONSE)]
        t += 100 * MS
    # The reader dropped the second half of an answer and the next exchange's request.
    cut = Chunk(t + 12 * MS, RESPONSE[:6])
    later = [Chunk(t + 400 * MS, REQUEST), Chunk(t + 412 * MS, RESPONSE), Chunk(t + 500 * MS, REQUEST),
             Chunk(t + 512 * MS, RESPONSE)]
    for item in [*exchanges, Chunk(t, REQUEST), cut, _Skipped(2, 15, t + 400 * MS), *later]:
        shared.reads.put(item)
    shared.stop.set()  # _drain waits on it for the refresh interval: not here
    clock.now = t + 2_000 * MS
    session._drain(clock)  # type: ignore[arg-type]
    session.finish()
    records = [json.loads(line) for line in out.getvalue().splitlines()]
    kinds = [r["kind"] for r in records]
    gap = kinds.index("gap")
    assert records[gap]["reads"] == 2 and records[gap]["bytes"] == 15 and records[gap]["t_ns"] == t + 400 * MS
    frames = [r for r in records if r["kind"] == "frame"]
    split = sum(1 for kind in kinds[:gap] if kind == "frame")
    before, after = frames[:split], frames[split:]
    # After the gap: exactly the two exchanges, paired, nothing invented.
    expected = [("request", True, []), ("response", True, [])] * 2
    assert [(f["role"], f["crc_ok"], f["flags"]) for f in after] == expected
    # Before it: the whole exchanges, the request, and the answer cut by the gap marked as such.
    assert all(f["crc_ok"] for f in before[:-1]) and "truncated" in before[-1]["flags"]
    assert not any(f["role"] in ("noise", "unknown") for f in before[:-1] + after)
    summary = records[-1]
    assert summary["kind"] == "summary" and summary["skipped_reads"] == 2 and summary["skipped_bytes"] == 15


@pytest.mark.parametrize("answer_in_flight", [True, False])
def test_an_answer_read_in_time_but_queued_late_is_no_timeout(answer_in_flight: bool) -> None:
    """The reader stamped the answer 12 ms after the request and was then held up (a loaded
    machine) before queueing it, while the decoder woke 500 ms later: with the read in flight,
    the decoder's clock stops where it began, and the answer pairs. The same drain with no read
    in flight (the answer really not there) times the request out: what a decoder that took the
    time alone did with the late-queued answer too."""
    out, clock = io.StringIO(), Clock()
    shared = _Shared(threading.Event(), queue.Queue())
    session = _session(out, shared, response_timeout_ns=100 * MS)
    shared.stop.set()  # _drain waits on it for the refresh interval: not here
    shared.reads.put(Chunk(T0, REQUEST))
    clock.now, clock.in_flight = T0 + 500 * MS, (T0 + 11 * MS if answer_in_flight else None)
    session._drain(clock)  # type: ignore[arg-type]
    shared.reads.put(Chunk(T0 + 12 * MS, RESPONSE))
    clock.now, clock.in_flight = T0 + 600 * MS, None
    session._drain(clock)  # type: ignore[arg-type]
    session.finish()
    frames = [r for r in map(json.loads, out.getvalue().splitlines()) if r["kind"] == "frame"]
    if answer_in_flight:
        assert [(f["role"], f["flags"], f["request_index"]) for f in frames] == [
            ("request", [], None), ("response", [], 0)]
    else:
        assert [(f["role"], f["flags"]) for f in frames] == [("request", ["timeout"]), ("response", ["unexpected"])]


def test_a_stop_signal_waits_for_the_record_being_written() -> None:
    """SIGTERM while a JSONL record is written (a consumer that reads slowly) stops the capture
    after the write, never inside a line; a second signal stops it at once."""
    import signal

    from sniffer.stopping import StopRequest, TerminatedError

    shared = _Shared(threading.Event(), queue.Queue())
    request = StopRequest(shared.stop)
    with pytest.raises(TerminatedError):
        request.handle(signal.SIGTERM, None)  # not writing: at once
    request.writing = True
    request.handle(signal.SIGTERM, None)  # writing: asked, not raised
    assert request.asked == signal.SIGTERM and shared.stop.is_set()
    with pytest.raises(KeyboardInterrupt):
        request.handle(signal.SIGINT, None)  # again: at once


def test_records_written_under_signals_are_whole() -> None:
    """A stop signal that interrupts a large write to a full pipe: every byte still arrives (CPython's
    buffered writer drops part of such a write even when the handler returns)."""
    import os
    import signal
    import sys
    import time

    from sniffer.stopping import whole_writes

    if sys.platform == "win32":
        pytest.skip("signals interrupting writes are POSIX")
    read_end, write_end = os.pipe()
    received = bytearray()

    def slow_reader() -> None:  # a consumer that stops reading for a while: the pipe fills
        time.sleep(0.3)
        while chunk := os.read(read_end, 65536):
            received.extend(chunk)

    reader = threading.Thread(target=slow_reader)
    reader.start()
    previous = signal.signal(signal.SIGALRM, lambda *_: None)
    signal.setitimer(signal.ITIMER_REAL, 0.1)  # while the write waits on the full pipe
    lines = "".join(f"{i:06d} {'x' * 500}\n" for i in range(400))
    try:
        with os.fdopen(write_end, "w") as stream:
            out = whole_writes(stream)
            for start in range(0, len(lines), 50_000):
                out.write(lines[start : start + 50_000])
                out.flush()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    reader.join(timeout=60)
    os.close(read_end)
    assert bytes(received) == lines.encode()
