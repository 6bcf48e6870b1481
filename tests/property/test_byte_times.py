"""Hypothesis: the table-driven byte times are the reference's, byte for byte."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from decoders.byte_times import byte_times, byte_times_reference
from decoders.capture import ChunkBatch

T0 = 1_600_000_000_000_000_000


@st.composite
def batches(draw: st.DrawFn) -> ChunkBatch:
    """Chunks of 0 to 300 bytes (empty ones too), at times that may go back (overlapping reads)."""
    lengths = draw(st.lists(st.integers(0, 300), min_size=1, max_size=40))
    steps = draw(st.lists(st.integers(-2_000_000, 50_000_000), min_size=len(lengths), max_size=len(lengths)))
    ends = np.cumsum(np.array(lengths, np.int64))
    times = T0 + np.cumsum(np.array(steps, np.int64))
    return ChunkBatch(data=bytes(int(ends[-1])), ends=ends, t_end_ns=times)


@given(batches(), st.sampled_from([11e9 / 115200, 11e9 / 9600, 10e9 / 19200, 1e9 / 3, 1.0, 104166.66666666667]))
def test_byte_times_match_the_reference(batch: ChunkBatch, char_time_ns: float) -> None:
    starts, ends = byte_times(batch, char_time_ns)
    reference_starts, reference_ends = byte_times_reference(batch, char_time_ns)
    assert starts.dtype == ends.dtype == np.int64
    assert starts.tolist() == reference_starts.tolist()
    assert ends.tolist() == reference_ends.tolist()


def test_an_empty_batch_has_no_times() -> None:
    empty = ChunkBatch(data=b"", ends=np.zeros(0, np.int64), t_end_ns=np.zeros(0, np.int64))
    for times in (byte_times(empty, 1000.0), byte_times_reference(empty, 1000.0)):
        assert [len(t) for t in times] == [0, 0]
