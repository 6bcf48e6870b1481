"""Exact-timed captures from frames and silences, for samples, tests and benchmarks.

Bytes of one transmission are back to back unless a gap is inserted; every run of
contiguous bytes becomes one chunk stamped with the end of its last byte, which is
what an ``exact`` capture records.
"""

from __future__ import annotations

import random
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from decoders.capture import Chunk, ChunkBatch, Int64Array
from decoders.line import LineSettings


@dataclass(frozen=True, slots=True)
class Transmission:
    """Bytes put on the wire after ``idle_before_ns`` of silence.

    ``gaps_ns`` maps a byte position to an extra silence before that byte.
    """

    data: bytes
    idle_before_ns: int
    gaps_ns: Mapping[int, int] = field(default_factory=dict)


def exact_chunks(transmissions: Iterable[Transmission], line: LineSettings, t0_ns: int) -> Iterator[Chunk]:
    """The chunks an exact tap records; the first transmission starts at ``t0_ns`` + its idle."""
    char = line.char_time_ns
    wire_free_ns = t0_ns
    for transmission in transmissions:
        run_start_ns = wire_free_ns + transmission.idle_before_ns
        cuts = sorted(p for p in transmission.gaps_ns if 0 < p < len(transmission.data))
        bounds = [0, *cuts, len(transmission.data)]
        for begin, end in pairwise(bounds):
            if begin:
                run_start_ns += transmission.gaps_ns[begin]
            run_end_ns = run_start_ns + round((end - begin) * char)
            yield Chunk(run_end_ns, transmission.data[begin:end])
            run_start_ns = run_end_ns
        wire_free_ns = run_start_ns


def usb_adapter_chunks(
    chunks: Iterable[Chunk],
    line: LineSettings,
    *,
    latency_ns: int = 16_000_000,
    buffer_bytes: int = 62,
    host_jitter_ns: int = 300_000,
    seed: int = 0,
) -> list[Chunk]:
    """What a host reading a USB-serial adapter records of an exact capture.

    The adapter (modelled on FTDI chips) sends a packet when its buffer holds
    ``buffer_bytes`` or when its latency timer, which ticks every ``latency_ns``,
    expires with data waiting; the host's read returns up to ``host_jitter_ns``
    later and is stamped then.
    """
    rng = random.Random(seed)
    byte_ends: list[int] = []
    data = bytearray()
    for chunk in chunks:
        last = len(chunk.data) - 1
        byte_ends.extend(chunk.t_end_ns - round((last - i) * line.char_time_ns) for i in range(len(chunk.data)))
        data += chunk.data
    phase = rng.randrange(latency_ns)
    delivered: list[Chunk] = []
    pending_from = 0
    last_read = 0

    def next_tick(after: int) -> int:
        return after + ((phase - after) % latency_ns or latency_ns)

    def deliver(until: int, at: int) -> None:
        nonlocal pending_from, last_read
        last_read = max(at + rng.randrange(host_jitter_ns + 1), last_read)
        delivered.append(Chunk(last_read, bytes(data[pending_from:until])))
        pending_from = until

    for index, end in enumerate(byte_ends):
        if pending_from < index and (tick := next_tick(byte_ends[pending_from])) < end:
            deliver(index, tick)
        if index + 1 - pending_from >= buffer_bytes:
            deliver(index + 1, end)
    if pending_from < len(data):
        deliver(len(data), next_tick(byte_ends[pending_from]))
    return delivered


def byte_times(batch: ChunkBatch, char_time_ns: float) -> tuple[Int64Array, Int64Array]:
    """(start of start bit, end of stop bit) of every byte of ``batch``, in integer ns, from the
    rule of :mod:`decoders.byte_times` computed byte by byte: the wire models' times, and what
    the tests hold the framer's :class:`~decoders.byte_times.ByteClock` to."""
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
