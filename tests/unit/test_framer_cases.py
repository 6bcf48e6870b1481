"""The framer on the conditions of real lines, against a pymodbus-built corpus with ground truth."""

from __future__ import annotations

import pytest

from decoders.capture import ChunkBatch, TimingQuality
from decoders.framer import Framer
from tests.corpus import LINES, SCENARIOS, Corpus, Expected, Score, build, host_expected, score, usb_adapter


def run_framer(corpus: Corpus, batch_chunks: int = 64) -> list[tuple[bytes, bool, bool, frozenset[str]]]:
    framer = Framer(corpus.line, corpus.timing)
    frames = []
    for start in range(0, len(corpus.chunks), batch_chunks):
        frames.extend(framer.feed(ChunkBatch.from_chunks(corpus.chunks[start : start + batch_chunks])))
    frames.extend(framer.flush())
    return [(f.data, f.is_noise, f.crc_ok, frozenset(f.flags.names)) for f in frames]


def describe(result: Score) -> str:
    return (f"found {result.frames_found}/{result.frames}, spurious {result.spurious_valid}, "
            f"exact pieces {result.pieces_exact}/{result.pieces}, false {result.false_flags}, "
            f"missed {result.missed_flags}")


@pytest.mark.parametrize("line", LINES, ids=lambda line: line.format())
@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_exact_captures_are_framed_exactly(scenario: object, line: object) -> None:
    corpus = build(scenario, line, exchanges=150)  # type: ignore[arg-type]
    emitted = run_framer(corpus)
    result = score(corpus.expected, emitted)
    assert result.recall == 1.0 and result.spurious_valid == 0, describe(result)
    assert result.false_flags.get("gap_1_5", 0) == 0, describe(result)
    assert result.pieces_exact == result.pieces, describe(result)
    assert not result.false_flags and not result.missed_flags, describe(result)
    assert b"".join(e[0] for e in emitted) == b"".join(c.data for c in corpus.chunks)


@pytest.mark.parametrize("latency_ms", [1.0, 16.0])
@pytest.mark.parametrize("line", LINES, ids=lambda line: line.format())
@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_host_captures(scenario: object, line: object, latency_ms: float) -> None:
    corpus = usb_adapter(build(scenario, line, exchanges=150), latency_ms=latency_ms)  # type: ignore[arg-type]
    assert corpus.timing is TimingQuality.HOST
    emitted = run_framer(corpus)
    result = score(host_expected(corpus.expected), emitted)
    assert result.recall >= 0.99, describe(result)
    assert result.spurious_valid == 0, describe(result)
    assert not result.false_flags.get("gap_1_5") and not result.false_flags.get("short_idle")
    assert b"".join(e[0] for e in emitted) == b"".join(c.data for c in corpus.chunks)


def test_glitch_after_a_frame_is_noise_and_the_frame_is_intact() -> None:
    from decoders.line import LineSettings
    from decoders.synthesis import Transmission, exact_chunks

    line = LineSettings.parse("19200 8E1")
    request = bytes.fromhex("02030C1E0004276C")
    chunks = list(exact_chunks([Transmission(request, 0), Transmission(b"\x00", 100_000)], line, 0))
    emitted = run_framer(Corpus("glitch", line, TimingQuality.EXACT, chunks, [Expected(request)]))
    assert emitted == [(request, False, True, frozenset()), (b"\x00", True, False, frozenset())]
