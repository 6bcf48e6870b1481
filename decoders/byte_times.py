"""Per-byte wire times from chunk times, vectorised.

A chunk's time is the end of its last byte. Inside a chunk the bytes are taken to
be back to back (exactly so for ``exact`` captures; the latest possible placement
for ``host`` captures), so byte *j* of an *n*-byte chunk ends ``n - 1 - j``
character times, and starts ``n - j`` character times, before the chunk's time.
Both are rounded to whole nanoseconds from the chunk's time, so that a silence
between two chunks is exactly the difference of their recorded times.

:func:`byte_times` looks the rounded offsets up in a table (one entry per character count
up to the longest chunk) and takes each byte's end from the next byte's start; about
twice as fast as :func:`byte_times_reference`, which computes every byte's offsets
from the rule above and which the tests hold it to.
"""

from __future__ import annotations

import numpy as np

from decoders.capture import ChunkBatch, Int64Array


def byte_times(batch: ChunkBatch, char_time_ns: float) -> tuple[Int64Array, Int64Array]:
    """(start of start bit, end of stop bit) of every byte of ``batch``, in integer ns."""
    total = len(batch.data)
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lengths = np.diff(batch.ends, prepend=0)
    # offsets[k]: k character times, rounded (the same product the reference rounds)
    offsets = np.rint(np.arange(int(lengths.max()) + 1, dtype=np.int64) * char_time_ns).astype(np.int64)
    chars_to_chunk_end = np.repeat(batch.ends, lengths)
    chars_to_chunk_end -= np.arange(total, dtype=np.int64)
    starts = np.repeat(batch.t_end_ns, lengths)
    starts -= offsets[chars_to_chunk_end]
    # Inside a chunk a byte ends where the next one starts; a chunk's last byte ends at its time.
    ends = np.empty_like(starts)
    ends[:-1] = starts[1:]
    filled = lengths > 0
    ends[batch.ends[filled] - 1] = batch.t_end_ns[filled]
    return starts, ends


def byte_times_reference(batch: ChunkBatch, char_time_ns: float) -> tuple[Int64Array, Int64Array]:
    """:func:`byte_times` computed byte by byte from the rule (the plain path)."""
    total = len(batch.data)
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    lengths = np.diff(batch.ends, prepend=0)
    chunk_of_byte = np.repeat(np.arange(len(batch.ends)), lengths)
    chars_after = batch.ends[chunk_of_byte] - 1 - np.arange(total, dtype=np.int64)
    chunk_end = batch.t_end_ns[chunk_of_byte]
    ends = chunk_end - np.rint(chars_after * char_time_ns).astype(np.int64)
    starts = chunk_end - np.rint((chars_after + 1) * char_time_ns).astype(np.int64)
    return starts, ends
