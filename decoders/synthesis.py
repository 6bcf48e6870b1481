"""Exact-timed captures from frames and silences, for samples, tests and benchmarks.

Bytes of one transmission are back to back unless a gap is inserted; every run of
contiguous bytes becomes one chunk stamped with the end of its last byte, which is
what an ``exact`` capture records.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from itertools import pairwise

from decoders.capture import Chunk
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
