"""The framer on the conditions of real lines, against a pymodbus-built corpus with ground truth."""

from __future__ import annotations

import pytest

from benchmarks.read_loops import READ_LOOPS
from decoders.capture import ChunkBatch, TimingQuality
from decoders.framer import Framer
from tests.corpus import LINES, SCENARIOS, Corpus, Expected, Score, build, deliver, host_expected, score


def run_framer(
    corpus: Corpus, batch_chunks: int = 64, *, fast: bool = True
) -> list[tuple[bytes, bool, bool, frozenset[str]]]:
    framer = Framer(corpus.line, corpus.timing, fast=fast)
    frames = []
    for start in range(0, len(corpus.chunks), batch_chunks):
        frames.extend(framer.feed(ChunkBatch.from_chunks(corpus.chunks[start : start + batch_chunks])))
    frames.extend(framer.flush())
    return [(f.data, f.is_noise, f.crc_ok, frozenset(f.flags.names)) for f in frames]


def describe(result: Score) -> str:
    return (f"found {result.frames_found}/{result.frames}, spurious {result.spurious_valid}, "
            f"exact pieces {result.pieces_exact}/{result.pieces}, false {result.false_flags}, "
            f"missed {result.missed_flags}")


@pytest.mark.parametrize("fast", [True, False], ids=["fast", "reference"])
@pytest.mark.parametrize("line", LINES, ids=lambda line: line.format())
@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_exact_captures_are_framed_exactly(scenario: object, line: object, fast: bool) -> None:
    corpus = build(scenario, line, exchanges=150)  # type: ignore[arg-type]
    emitted = run_framer(corpus, fast=fast)
    result = score(corpus.expected, emitted)
    assert result.recall == 1.0 and result.spurious_valid == 0, describe(result)
    assert result.false_flags.get("gap_1_5", 0) == 0, describe(result)
    assert result.pieces_exact == result.pieces, describe(result)
    assert not result.false_flags and not result.missed_flags, describe(result)
    assert b"".join(e[0] for e in emitted) == b"".join(c.data for c in corpus.chunks)


@pytest.mark.parametrize("read_loop", sorted(READ_LOOPS))
@pytest.mark.parametrize("line", LINES, ids=lambda line: line.format())
@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_host_captures(scenario: object, line: object, read_loop: str) -> None:
    corpus = deliver(build(scenario, line, exchanges=150), read_loop)  # type: ignore[arg-type]
    assert corpus.timing is TimingQuality.HOST
    emitted = run_framer(corpus)
    result = score(host_expected(corpus.expected), emitted)
    assert result.recall == 1.0, describe(result)
    assert result.spurious_valid == 0, describe(result)
    assert not result.false_flags.get("gap_1_5") and not result.false_flags.get("short_idle")
    assert b"".join(e[0] for e in emitted) == b"".join(c.data for c in corpus.chunks)


@pytest.mark.parametrize("scenario", [s for s in SCENARIOS if s.name in ("glitch-polling", "junk-both-sides",
                                                                        "broken-answers", "everything")],
                         ids=lambda s: s.name)
def test_host_reference_agrees_with_the_fast_path(scenario: object) -> None:
    corpus = deliver(build(scenario, LINES[1], exchanges=100), "random-sizes")  # type: ignore[arg-type]
    assert run_framer(corpus, fast=False) == run_framer(corpus)


def test_glitch_after_a_frame_is_noise_and_the_frame_is_intact() -> None:
    from benchmarks.wire_synthesis import Transmission, exact_chunks
    from decoders.line import LineSettings

    line = LineSettings.parse("19200 8E1")
    request = bytes.fromhex("02030C1E0004276C")
    chunks = list(exact_chunks([Transmission(request, 0), Transmission(b"\x00", 100_000)], line, 0))
    emitted = run_framer(Corpus("glitch", line, TimingQuality.EXACT, chunks, [Expected(request)]))
    assert emitted == [(request, False, True, frozenset()), (b"\x00", True, False, frozenset())]


@pytest.mark.parametrize("fast", [True, False], ids=["fast", "reference"])
def test_an_answer_and_two_zero_glitch_bytes_are_no_request(fast: bool) -> None:
    """An FC 2 answer of 6 bytes with two 0x00 bytes right behind it passes the CRC as 8 bytes,
    an FC 2 request's length: asking for 0x57CC inputs, more than a request may ask for (2000).
    The answer to the open request and its glitch, as the property test found (seed 39)."""
    from benchmarks.wire_synthesis import Transmission, exact_chunks
    from decoders.line import LineSettings

    line = LineSettings.parse("9600 8E1")
    request, answer = bytes.fromhex("E2025DC10001EDC9"), bytes.fromhex("E202010157CC")
    chunks = list(exact_chunks([Transmission(request, 0), Transmission(answer, 13_600_000),
                                Transmission(b"\x00\x00", 0)], line, 0))
    emitted = run_framer(Corpus("glitch", line, TimingQuality.EXACT, chunks, [Expected(request), Expected(answer)]),
                         fast=fast)
    assert [(data, noise, crc_ok) for data, noise, crc_ok, _ in emitted] == [
        (request, False, True), (answer, False, True), (b"\x00\x00", True, False)]


@pytest.mark.parametrize("read_loop", ["slow-delivery", "read-timeout"])
def test_slow_delivery_still_pairs_every_answered_request(read_loop: str) -> None:
    """An answer a read (a read timeout) after its request pairs with it: the response
    timeout on host captures is derived from the capture's own delivery delay."""
    from decoders.message import Role
    from decoders.pipeline import Decoder

    corpus = deliver(build(SCENARIOS[0], LINES[0], exchanges=200), read_loop)
    decoder = Decoder(corpus.line, corpus.timing)
    batches = [ChunkBatch.from_chunks(corpus.chunks[i : i + 20]) for i in range(0, len(corpus.chunks), 20)]
    messages = [m for batch in batches for part in decoder.feed(batch) for m in part]
    messages += [m for part in decoder.flush() for m in part]
    roles = [m.role for m in messages]
    assert roles.count(Role.REQUEST) == roles.count(Role.RESPONSE) + roles.count(Role.EXCEPTION) == 200
    assert all(m.request_index is not None for m in messages if m.role in (Role.RESPONSE, Role.EXCEPTION))
    assert not any(m.flags.names for m in messages if m.role is not Role.REQUEST or "timeout" in m.flags.names)
    assert decoder.matcher.timeout_ns >= 2 * decoder.framer.delivery_delay_ns > 300_000_000
