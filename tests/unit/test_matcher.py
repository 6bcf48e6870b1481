"""Roles and pairing on one wire."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.crc import crc_bytes, crc_ok
from decoders.frame import Frame, FrameFlag, frames_to_batch
from decoders.message import Message, Role
from decoders.modbus.matcher import MAX_TIMEOUT_NS, MIN_TIMEOUT_NS, Matcher

MS = 1_000_000


def adu(hex_body: str) -> bytes:
    body = bytes.fromhex(hex_body.replace(" ", ""))
    return body + crc_bytes(body)


READ_2 = adu("02 03 0C1E 0004")
ANSWER_2 = adu("02 03 08 0028 0258 01F4 0000")
READ_5 = adu("05 03 0000 0002")
ANSWER_5 = adu("05 03 04 0001 0002")
WRITE_2 = adu("02 06 2329 000D")


def run(*frames: tuple[float, bytes], timeout_ms: float | None = None) -> list[Message]:
    """Frames at the given start times (ms); each lasts 1 ms per 10 bytes."""
    matcher = Matcher(None if timeout_ms is None else int(timeout_ms * MS))
    out: list[Message] = []
    for index, (start_ms, data) in enumerate(frames):
        start = int(start_ms * MS)
        frame = Frame(index, start, start + len(data) * MS // 10, data, crc_ok(data), FrameFlag.NONE)
        out.extend(matcher.feed(frames_to_batch([frame])))
    return out + list(matcher.flush())


def roles(messages: list[Message]) -> list[tuple[str, int | None, list[str]]]:
    return [(m.role.value, m.request_index, m.flags.names) for m in messages]


def test_request_and_response_pair_with_latency() -> None:
    request, response = run((0, READ_2), (5, ANSWER_2))
    assert (request.role, response.role) == (Role.REQUEST, Role.RESPONSE)
    assert response.request_index == 0
    assert response.latency_ns == 5 * MS - len(READ_2) * MS // 10


def test_echoes_by_order() -> None:
    assert roles(run((0, WRITE_2), (5, WRITE_2), (50, WRITE_2), (55, WRITE_2))) == [
        ("request", None, []), ("response", 0, []), ("request", None, []), ("response", 2, []),
    ]


def test_unanswered_request_times_out_when_the_same_slave_is_asked_again() -> None:
    assert roles(run((0, READ_2), (30, READ_2), (35, ANSWER_2))) == [
        ("request", None, ["timeout"]), ("request", None, ["retry"]), ("response", 1, []),
    ]


def test_timeout_by_time() -> None:
    result = run((0, READ_2), (50, READ_5), (55, ANSWER_5), (300, READ_5), timeout_ms=100)
    assert roles(result)[0] == ("request", None, ["timeout"])


def test_no_verdict_for_a_request_open_at_the_end() -> None:
    assert roles(run((0, READ_2))) == [("request", None, [])]


def test_requests_to_other_slaves_interleave() -> None:
    """Two masters: requests to slaves 2 and 5 overlap; each answer finds its own request."""
    assert roles(run((0, READ_2), (2, READ_5), (6, ANSWER_2), (9, ANSWER_5))) == [
        ("request", None, []), ("request", None, []), ("response", 0, []), ("response", 1, []),
    ]


def test_unexpected_answers() -> None:
    wrong_function = adu("02 04 08 0028 0258 01F4 0000")
    wrong_count = adu("02 03 02 0028")
    result = run((0, READ_5), (3, ANSWER_5), (5, ANSWER_2), (10, READ_2), (15, wrong_function), (20, wrong_count),
                 (25, ANSWER_5))
    # The request is still open when the capture ends: no verdict.
    assert [m.flags.names for m in result][2:] == [["unexpected"], [], ["unexpected"], ["unexpected"], ["unexpected"]]
    assert [m.role for m in result][2:] == [Role.RESPONSE, Role.REQUEST, Role.RESPONSE, Role.RESPONSE, Role.RESPONSE]


def test_answers_before_the_first_request_are_not_unexpected() -> None:
    """A recording that begins between a request and its answer (each rotated file read alone):
    its first answers have a request the capture never saw. From the first request on, an
    answer nobody asked for is unexpected again."""
    result = run((0, ANSWER_2), (2, adu("05 83 02")), (10, READ_2), (15, ANSWER_2), (20, ANSWER_5))
    assert roles(result) == [("response", None, []), ("exception", None, []), ("request", None, []),
                             ("response", 2, []), ("response", None, ["unexpected"])]
    for bulk in (True, False):  # pairs settled in bulk count as requests seen too
        matcher, times = Matcher(bulk=bulk), [(0, READ_2), (5, ANSWER_2), (10, READ_5), (15, ANSWER_5), (20, ANSWER_2)]
        frames = [Frame(i, int(t * MS), int(t * MS) + len(data) * MS // 10, data, crc_ok(data), FrameFlag.NONE)
                  for i, (t, data) in enumerate(times)]
        out = [*matcher.feed(frames_to_batch(frames)), *matcher.flush()]
        assert [m.flags.names for m in out] == [[], [], [], [], ["unexpected"]], bulk


def test_exception_pairs_with_its_request() -> None:
    _, exception = run((0, READ_2), (4, adu("02 83 02")))
    assert exception.role is Role.EXCEPTION
    assert (exception.exception_code, exception.request_index) == (2, 0)
    assert not exception.flags


def test_broadcast_gets_no_answer_and_a_reply_is_unexpected() -> None:
    broadcast = adu("00 06 2329 000D")
    result = run((0, broadcast), (5, broadcast), (50, READ_2), (55, ANSWER_2))
    assert roles(result) == [("broadcast", None, []), ("response", None, ["unexpected"]),
                             ("request", None, []), ("response", 2, [])]


def test_a_broadcast_repeated_after_the_timeout_is_a_broadcast_again() -> None:
    broadcast = adu("00 06 2329 000D")
    result = run((0, broadcast), (5, broadcast), (150, broadcast), (300, broadcast), (302, broadcast))
    assert roles(result) == [("broadcast", None, []), ("response", None, ["unexpected"]),
                             ("broadcast", None, []), ("broadcast", None, []), ("response", None, ["unexpected"])]
    fixed = run((0, broadcast), (150, broadcast), timeout_ms=200)
    assert roles(fixed) == [("broadcast", None, []), ("response", None, ["unexpected"])]


def test_crc_error_answer_makes_the_repeat_a_retry() -> None:
    damaged = bytearray(ANSWER_2)
    damaged[5] ^= 1
    result = run((0, READ_2), (5, bytes(damaged)), (40, READ_2), (45, ANSWER_2))
    assert roles(result) == [("request", None, []), ("response", 0, []), ("request", None, ["retry"]),
                             ("response", 2, [])]


def test_late_answer_after_the_timeout_is_unexpected() -> None:
    assert roles(run((0, READ_2), (150, ANSWER_2), timeout_ms=100)) == [
        ("request", None, ["timeout"]), ("response", None, ["unexpected"]),
    ]


def test_adaptive_timeout_follows_the_traffic() -> None:
    matcher = Matcher()
    assert matcher.timeout_ns == MAX_TIMEOUT_NS
    frames = []
    for i in range(40):
        start = i * 50 * MS
        frames += [Frame(2 * i, start, start + MS, READ_2, True, FrameFlag.NONE),
                   Frame(2 * i + 1, start + 4 * MS, start + 5 * MS, ANSWER_2, True, FrameFlag.NONE)]
    matcher.feed(frames_to_batch(frames))
    assert matcher.timeout_ns == MIN_TIMEOUT_NS  # 10 x 3 ms latency is below the 100 ms floor


def test_messages_leave_in_capture_order() -> None:
    result = run((0, READ_2), (2, READ_5), (3, b"\x00\x01"), (6, ANSWER_2), (9, ANSWER_5))
    assert [m.frame.index for m in result] == [0, 1, 2, 3, 4]


def test_same_result_whatever_the_batches() -> None:
    from decoders.frame import slice_frames

    sequence = [(0, READ_2), (2, READ_5), (6, ANSWER_2), (9, ANSWER_5), (30, WRITE_2), (33, WRITE_2),
                (60, READ_2), (200, READ_2), (205, ANSWER_2)]
    frames = []
    for index, (start_ms, data) in enumerate(sequence):
        start = int(start_ms * MS)
        frames.append(Frame(index, start, start + len(data) * MS // 10, data, crc_ok(data), FrameFlag.NONE))
    whole = frames_to_batch(frames)
    single = Matcher()
    reference = roles(list(single.feed(whole)) + list(single.flush()))
    assert reference[-1] == ("response", 7, [])
    for cut in range(1, len(frames)):
        matcher = Matcher()
        parts = [slice_frames(whole, 0, cut), slice_frames(whole, cut, len(frames))]
        result = [m for part in parts for m in matcher.feed(part)] + list(matcher.flush())
        assert roles(result) == reference, cut


def test_damaged_exception_answer_makes_the_repeat_a_retry() -> None:
    damaged = bytearray(adu("02 83 02"))
    damaged[-1] ^= 0xFF
    result = run((0, READ_2), (4, bytes(damaged)), (40, READ_2), (44, ANSWER_2))
    assert roles(result) == [("request", None, []), ("exception", 0, []), ("request", None, ["retry"]),
                             ("response", 2, [])]


@pytest.mark.parametrize("chunks_per_batch", [50, 400])
def test_bulk_settling_changes_nothing(chunks_per_batch: int) -> None:
    """On traffic with every fault the corpus knows, bulk runs and the frame-by-frame loop agree;
    in batches of more frames than the loop's window of lists (WINDOW in pair_runs) too."""
    from decoders.capture import ChunkBatch
    from decoders.framer import Framer
    from tests.corpus import LINES, SCENARIOS, build

    for scenario in SCENARIOS:
        corpus = build(scenario, LINES[1], exchanges=200)
        framer = Framer(corpus.line)
        pieces = range(0, len(corpus.chunks), chunks_per_batch)
        batches = [framer.feed(ChunkBatch.from_chunks(corpus.chunks[i : i + chunks_per_batch])) for i in pieces]
        batches.append(framer.flush())
        results = []
        for bulk in (True, False):
            matcher = Matcher()
            matcher.bulk = bulk
            messages = [m for batch in batches for m in matcher.feed(batch)] + list(matcher.flush())
            results.append([(m.role, m.flags, m.request_index, m.latency_ns, m.exception_code) for m in messages])
            timeouts = matcher.timeout_ns
        assert results[0] == results[1], scenario.name
        assert timeouts >= MIN_TIMEOUT_NS


def test_a_fixed_timeout_shorter_than_a_derived_one_holds_in_one_batch() -> None:
    """``--response-timeout 50``: answers 70 ms late are timeouts and unexpected answers, also
    where the whole exchange comes in one batch (a run of pairs the bulk path would settle)."""
    frames = []
    for pair in range(4):
        for start_ms, data in ((pair * 200, READ_2), (pair * 200 + 72, ANSWER_2)):
            start = start_ms * MS
            frames.append(Frame(len(frames), start, start + len(data) * MS // 10, data, True, FrameFlag.NONE))
    matcher = Matcher(response_timeout_ns=50 * MS)
    out = list(matcher.feed(frames_to_batch(frames))) + list(matcher.flush())
    assert [m.flags.names for m in out] == [["timeout"], ["unexpected"]] + [["timeout", "retry"], ["unexpected"]] * 3
    assert all(m.request_index is None for m in out)


def test_latency_window_learned_in_bulk_as_one_by_one() -> None:
    import random

    from decoders.modbus.matcher import LATENCY_WINDOW, LEARN_EVERY, TIMEOUT_PER_LATENCY

    rng = random.Random(4)
    latencies = [rng.randrange(1, 30_000_000) for _ in range(1000)]
    window: list[int] = []
    expected = []
    timeout = MAX_TIMEOUT_NS
    for learned, latency in enumerate(latencies, 1):
        window = [*window, latency][-LATENCY_WINDOW:]
        if learned < LEARN_EVERY or learned % LEARN_EVERY == 0:
            timeout = min(MAX_TIMEOUT_NS, max(MIN_TIMEOUT_NS, TIMEOUT_PER_LATENCY * max(window)))
        expected.append(timeout)
    matcher, position = Matcher(), 0
    for size in [1, 5, 40, 3, 64, 100, 7, 300, 480]:
        matcher._learn_many(np.array(latencies[position : position + size], np.int64))
        position += size
        assert matcher.timeout_ns == expected[position - 1], position
    one_by_one = Matcher()  # the answers the loop visits: _learn_one, interleaved with runs
    position = 0
    for size in [1, 1, 29, 2, 1, 33, 1, 100, 1, 1, 300, 1]:
        if size == 1:
            one_by_one._learn_one(latencies[position])
        else:
            one_by_one._learn_many(np.array(latencies[position : position + size], np.int64))
        position += size
        assert one_by_one.timeout_ns == expected[position - 1], position
    for latency in latencies[position:]:
        one_by_one._learn_one(latency)
        position += 1
        assert one_by_one.timeout_ns == expected[position - 1], position


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(1, 600_000_000), min_size=1, max_size=900),
       st.lists(st.integers(1, 400), min_size=1, max_size=40))
def test_any_runs_of_answers_learn_as_one_by_one(latencies: list[int], sizes: list[int]) -> None:
    """The timeout after each run of answers learned at once is the one learned answer by answer,
    whatever the runs' lengths and the latencies (the window's longest found without a list)."""
    reference, runs, position = Matcher(), Matcher(), 0
    for size in sizes:
        part = latencies[position : position + size]
        if not part:
            break
        for latency in part:
            reference._learn_one(latency)
        runs._learn_many(np.array(part, np.int64))
        position += len(part)
        assert runs.timeout_ns == reference.timeout_ns, position


def test_a_run_sees_the_longest_latency_at_its_window_s_very_edge() -> None:
    """One long latency among short ones, at every place around the window's far edge when a
    run of answers is learned after others: it counts exactly while the window holds it."""
    from decoders.modbus.matcher import LATENCY_WINDOW, LEARN_EVERY

    # The window at the run's last checkpoint: partly before the run (earlier runs), or wholly
    # inside it (a run longer than the window), with one earlier answer in it, or none.
    cases = ((LATENCY_WINDOW + 40, 3 * LEARN_EVERY), (LATENCY_WINDOW, LEARN_EVERY), (70, 26),
             (LEARN_EVERY + 1, LATENCY_WINDOW - 1), (LEARN_EVERY, LATENCY_WINDOW + 44))
    for before, run in cases:
        checkpoint = (before + run) // LEARN_EVERY * LEARN_EVERY
        for spike in range(checkpoint - LATENCY_WINDOW - 2, checkpoint):
            latencies = [1_000_000] * (before + run)
            latencies[max(spike, 0)] = 400_000_000
            reference, runs = Matcher(), Matcher()
            for latency in latencies:
                reference._learn_one(latency)
            runs._learn_many(np.array(latencies[:before], np.int64))
            runs._learn_many(np.array(latencies[before:], np.int64))
            assert runs.timeout_ns == reference.timeout_ns, (before, run, spike)


def test_tick_times_out_and_releases_by_the_clock() -> None:
    matcher = Matcher(response_timeout_ns=100 * MS)
    frame = Frame(0, 0, MS, READ_2, True, FrameFlag.NONE)
    assert len(matcher.feed(frames_to_batch([frame]))) == 0  # held: outcome unknown
    assert len(matcher.tick(50 * MS)) == 0
    [released] = list(matcher.tick(200 * MS))
    assert released.flags.names == ["timeout"]


_DAMAGED_2 = ANSWER_2[:-1] + bytes([ANSWER_2[-1] ^ 0xFF])
_OTHER_READ_2 = adu("02 03 0C20 0004")
_OTHER_ANSWER_2 = adu("02 03 08 0001 0002 0003 0004")
#: What a step of the exchange puts on the wire after its request: the answer, a damaged
#: answer, an exception, or nothing (the slave is silent).
_STEPS = {
    "read 2": (READ_2, ANSWER_2), "read 2 damaged": (READ_2, _DAMAGED_2), "read 2 silent": (READ_2, None),
    "read 2 elsewhere": (_OTHER_READ_2, _OTHER_ANSWER_2), "read 2 exception": (READ_2, adu("02 83 02")),
    "read 5": (READ_5, ANSWER_5), "read 5 silent": (READ_5, None), "write 2": (WRITE_2, WRITE_2),
}


@given(st.lists(st.tuples(st.sampled_from(sorted(_STEPS)), st.integers(1, 300), st.sampled_from([3, 3, 3, 40, 90])),
                max_size=60),
       st.lists(st.integers(1, 9), min_size=1, max_size=8), st.sampled_from([None, None, 2, 20, 50, 150]))
def test_bulk_runs_with_failed_slaves_are_the_loop(steps: list[tuple[str, int, int]], splits: list[int],
                                                   timeout_ms: int | None) -> None:
    """Runs settled in bulk while slaves have failed (silent, damaged answers, exceptions) or are
    still open, their retries and the requests that are none, against the frame-by-frame loop;
    answers late for a fixed response timeout (``--response-timeout``) shorter than the least a
    derived one may be; batches split anywhere."""
    frames, now, index = [], 0, 0
    for name, pause_ms, latency_ms in steps:
        request, answer = _STEPS[name]
        for data in (request, answer):
            if data is not None:
                frames.append(Frame(index, now * MS, now * MS + len(data) * MS // 10, data, crc_ok(data),
                                    FrameFlag.NONE))
                index, now = index + 1, now + latency_ms
        now += pause_ms
    bulk, loop = _matched_both_ways(frames, splits, None if timeout_ms is None else timeout_ms * MS)
    assert bulk == loop


def _matched_both_ways(frames: list[Frame], splits: list[int],
                       timeout_ns: int | None = None) -> list[list[tuple[object, ...]]]:
    """What the matcher makes of ``frames`` in bulk and frame by frame, fed in batches of ``splits``."""
    results = []
    for bulk in (True, False):
        matcher, out, position, cut = Matcher(response_timeout_ns=timeout_ns, bulk=bulk), [], 0, 0
        while position < len(frames):
            size = splits[cut % len(splits)]
            out += matcher.feed(frames_to_batch(frames[position : position + size]))
            position, cut = position + size, cut + 1
        out += matcher.flush()
        results.append([(m.role, m.flags, m.request_index, m.latency_ns) for m in out])
    return results


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([3, 3, 3, 3, 90]), max_size=300),
       st.lists(st.sampled_from([3, 12, 45, 90]), max_size=90), st.integers(20, 700), st.integers(2, 40),
       st.lists(st.integers(1, 90), min_size=1, max_size=4))
def test_runs_beside_an_open_request_are_the_loop(before: list[int], after: list[int], late_ms: int, gap_ms: int,
                                                  splits: list[int]) -> None:
    """Slave 5's request left open (its answer comes late, past or within the timeout) while
    slave 2's pairs go on, their latencies moving the derived timeout at its checkpoints (after
    each of the first 31 answers, then every 32nd; up, or down as a long latency leaves the last
    256): the pairs settled in bulk beside the open request leave its timeout, its answer and
    their own pairing as the frame-by-frame loop does."""
    times: list[tuple[int, bytes]] = []
    now = 0
    for latency in [*before, None, *after]:
        if latency is None:
            opened, now = now, now + gap_ms
            times.append((opened, READ_5))
            continue
        times += [(now, READ_2), (now + latency, ANSWER_2)]
        now += latency + gap_ms
    asks = range(2 * len(before) + 1, len(times), 2)  # where slave 2's requests after the open one are
    late = next((k for k in asks if times[k][0] > opened + late_ms), len(times))
    times.insert(late, (opened + late_ms, ANSWER_5))  # between two of slave 2's pairs
    frames, end = [], 0
    for index, (start_ms, data) in enumerate(times):
        start = max(start_ms * MS, end + MS)
        end = start + len(data) * MS // 10
        frames.append(Frame(index, start, end, data, True, FrameFlag.NONE))
    bulk, loop = _matched_both_ways(frames, splits)
    assert bulk == loop
