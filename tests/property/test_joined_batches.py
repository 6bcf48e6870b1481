"""Hypothesis: chunk batches joined for counting (:func:`decoders.capture.joined_batches`) hold
every chunk as read, in order, at least the asked number a batch, and a quiet (an empty batch)
where it came."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from decoders.capture import Chunk, ChunkBatch, joined_batches


def _batches(sizes: list[int]) -> list[ChunkBatch]:
    batches, t_ns = [], 1_000
    for size in sizes:
        chunks = []
        for _ in range(size):
            t_ns += 7
            chunks.append(Chunk(t_ns, bytes([t_ns % 251, t_ns % 13]), channel=t_ns % 3))
        batches.append(ChunkBatch.from_chunks(chunks))
    return batches


@given(st.lists(st.integers(0, 9), max_size=20), st.integers(1, 25), st.integers(1, 60))
def test_joined_batches_keep_every_chunk_and_every_quiet(sizes: list[int], at_least: int, size: int) -> None:
    """Every chunk as read, in order; a batch ends once it holds ``at_least`` chunks or ``size``
    bytes (two bytes a chunk here), or at a quiet."""
    read = _batches(sizes)
    joined = list(joined_batches(iter(read), at_least, size))
    assert [chunk for batch in joined for chunk in batch.chunks()] == [c for b in read for c in b.chunks()]
    # A quiet ends what is held: the batches between two quiets are joined among themselves.
    runs: list[list[int]] = [[]]
    for batch in read:
        if len(batch):
            runs[-1].append(len(batch))
        else:
            runs.append([])
    expected = []
    for run in runs:
        held = 0
        for chunks in run:
            held += chunks
            if held >= at_least or 2 * held >= size:
                expected.append(held)
                held = 0
        if held:
            expected.append(held)
        expected.append(0)
    assert [len(batch) for batch in joined] == expected[:-1]
