"""Hypothesis: the framer's byte clock tells every byte's times as the rule computes them byte by
byte (:func:`benchmarks.wire_synthesis.byte_times`), and its silences are every silence of the run."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from benchmarks.wire_synthesis import byte_times
from decoders.byte_times import ByteClock, rounded_char_times
from decoders.capture import ChunkBatch

T0 = 1_600_000_000_000_000_000
CHAR_TIMES = st.sampled_from([11e9 / 115200, 11e9 / 9600, 10e9 / 19200, 1e9 / 3, 1.0, 104166.66666666667])


@st.composite
def batches(draw: st.DrawFn) -> ChunkBatch:
    """Chunks of 0 to 300 bytes (empty ones too), at times that may go back (overlapping reads)."""
    lengths = draw(st.lists(st.integers(0, 300), min_size=1, max_size=40))
    steps = draw(st.lists(st.integers(-2_000_000, 50_000_000), min_size=len(lengths), max_size=len(lengths)))
    ends = np.cumsum(np.array(lengths, np.int64))
    times = T0 + np.cumsum(np.array(steps, np.int64))
    return ChunkBatch(data=bytes(int(ends[-1])), ends=ends, t_end_ns=times)


def _clock_of_two(first: ChunkBatch, second: ChunkBatch, char_time_ns: float, kept_from: int) -> ByteClock:
    """The framer's way: a held tail of the first batch, then the second."""
    held = ByteClock.of(first, char_time_ns).tail(kept_from)
    return held.then(ByteClock.of(second, char_time_ns))


@given(batches(), batches(), CHAR_TIMES, st.integers(0, 12_000))
def test_the_byte_clock_tells_the_reference_times(first: ChunkBatch, second: ChunkBatch, char_time_ns: float,
                                                  kept: int) -> None:
    kept_from = min(kept, len(first.data))
    clock = _clock_of_two(first, second, char_time_ns, kept_from)
    reference_starts = np.concatenate([byte_times(batch, char_time_ns)[0] for batch in (first, second)])
    reference_ends = np.concatenate([byte_times(batch, char_time_ns)[1] for batch in (first, second)])
    reference_starts, reference_ends = reference_starts[kept_from:], reference_ends[kept_from:]
    every = np.arange(len(clock), dtype=np.int64)
    assert len(clock) == len(reference_starts)
    assert clock.starts_at(every).tolist() == reference_starts.tolist()
    assert clock.ends_at(every).tolist() == reference_ends.tolist()
    # Every silence between two bytes that is not zero is one the clock lists.
    silences = reference_starts[1:] - reference_ends[:-1]
    positions, clock_silences = clock.silences()
    assert np.all(np.diff(positions) > 0)
    listed = dict(zip(positions.tolist(), clock_silences.tolist(), strict=True))
    for position, silence in enumerate(silences.tolist(), start=1):
        assert listed.get(position, 0) == silence
    assert set(listed) <= set(range(1, len(clock)))


@given(batches(), CHAR_TIMES, st.data())
def test_runs_inside_one_chunk_are_timed_by_their_ends(batch: ChunkBatch, char_time_ns: float,
                                                       data: st.DataObject) -> None:
    clock = ByteClock.of(batch, char_time_ns)
    if not len(clock):
        return
    starts, ends = byte_times(batch, char_time_ns)
    chunk_starts = np.concatenate([[0], clock.ends[:-1]])
    chunk = data.draw(st.integers(0, len(clock.ends) - 1))
    begin = data.draw(st.integers(int(chunk_starts[chunk]), int(clock.ends[chunk]) - 1))
    stop = data.draw(st.integers(begin + 1, int(clock.ends[chunk])))
    run_starts, run_ends = clock.run_times(np.array([begin]), np.array([stop]))
    assert (int(run_starts[0]), int(run_ends[0])) == (int(starts[begin]), int(ends[stop - 1]))


def test_an_empty_batch_has_no_times() -> None:
    empty = ChunkBatch(data=b"", ends=np.zeros(0, np.int64), t_end_ns=np.zeros(0, np.int64))
    assert [len(t) for t in byte_times(empty, 1000.0)] == [0, 0]
    clock = ByteClock.of(empty, 1000.0)
    assert len(clock) == 0
    assert [len(part) for part in clock.silences()] == [0, 0]


@given(st.lists(st.lists(st.integers(-5, 70_000), max_size=30), min_size=1, max_size=4), CHAR_TIMES)
def test_char_times_rounded_by_table_as_by_multiplying(runs: list[list[int]], char_time_ns: float) -> None:
    """Counts the table holds and grows to hold, and those it does not (negative, past its most)."""
    for counts in runs:
        column = np.array(counts, np.int64)
        assert rounded_char_times(column, char_time_ns).tolist() == \
            np.rint(column * char_time_ns).astype(np.int64).tolist()


def _pieces_timed_as_the_reference_times_them(batch: ChunkBatch, char_time_ns: float, first: list[int],
                                              data: st.DataObject) -> None:
    """Pieces from each of ``first`` (the last up to a drawn end): the earliest start and the
    latest end of their bytes by the reference."""
    clock = ByteClock.of(batch, char_time_ns)
    stop = data.draw(st.integers(first[-1] + 1, len(clock)))
    starts_piece = np.zeros(stop + 1, np.bool_)
    starts_piece[first] = True
    t_start, t_end = clock.piece_times(clock.silences()[0], np.array(first, np.int64), starts_piece)
    starts, ends = byte_times(batch, char_time_ns)
    bounds = [*first, stop]
    assert t_start.tolist() == [int(starts[a:b].min()) for a, b in pairwise(bounds)]
    assert t_end.tolist() == [int(ends[a:b].max()) for a, b in pairwise(bounds)]


@given(batches(), CHAR_TIMES, st.data())
def test_pieces_are_timed_by_their_earliest_start_and_latest_end(batch: ChunkBatch, char_time_ns: float,
                                                                 data: st.DataObject) -> None:
    """A piece that chunks cut (a frame of two reads, reads whose times overlap) takes the
    earliest start and the latest end of its bytes, as the framer times frames."""
    size = int(batch.ends[-1])
    if not size:
        return
    first = sorted(data.draw(st.sets(st.integers(0, size - 1), min_size=1, max_size=30)))
    _pieces_timed_as_the_reference_times_them(batch, char_time_ns, first, data)


@given(batches(), CHAR_TIMES, st.data())
def test_pieces_that_begin_chunks_are_timed_as_the_reference_times_them(
    batch: ChunkBatch, char_time_ns: float, data: st.DataObject,
) -> None:
    """Pieces beginning where chunks begin (most frames are a chunk; a few, two or more), the
    first one perhaps inside a chunk: their chunks counted, not searched."""
    clock = ByteClock.of(batch, char_time_ns)
    if len(clock) < 2:
        return
    chunk_starts = np.concatenate([[0], clock.ends[:-1]]).tolist()
    begin = data.draw(st.sampled_from(chunk_starts) | st.integers(0, len(clock) - 1))
    later = [start for start in chunk_starts if start > begin]
    first = [begin, *(sorted(data.draw(st.sets(st.sampled_from(later)))) if later else [])]
    _pieces_timed_as_the_reference_times_them(batch, char_time_ns, first, data)
