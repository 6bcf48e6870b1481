"""Wire times of bytes from chunk times, vectorised.

A chunk's time is the end of its last byte. Inside a chunk the bytes are taken to
be back to back (exactly so for ``exact`` captures; the latest possible placement
for ``host`` captures), so byte *j* of an *n*-byte chunk ends ``n - 1 - j``
character times, and starts ``n - j`` character times, before the chunk's time.
Both are rounded to whole nanoseconds from the chunk's time, so that a silence
between two chunks is exactly the difference of their recorded times.

:class:`ByteClock` is what the framer uses: it keeps the chunks and computes the times of
the bytes asked for (frames' first and last bytes) and the silences where chunks meet. The
tests hold it to every byte's times computed from the rule above, byte by byte, as the
benchmarks' models of the wire take them (:func:`benchmarks.wire_synthesis.byte_times`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.capture import ChunkBatch, Int64Array

#: Character counts up to this are rounded by a table (see :func:`rounded_char_times`).
ROUNDED_TABLE_MOST = 1 << 16
#: Per character time: ``rint(k * char_time_ns)`` for k = 0, 1, ... (grown as asked).
_ROUNDED: dict[float, Int64Array] = {}


def rounded_char_times(counts: Int64Array, char_time_ns: float) -> Int64Array:
    """``np.rint(counts * char_time_ns)`` as integers, by a gather from a table of the same
    products (faster than multiplying, rounding and casting every count); counts
    the table does not hold (negative, or a read longer than ``ROUNDED_TABLE_MOST``) the plain way."""
    if not len(counts):
        return np.zeros(0, np.int64)
    low, high = int(counts.min()), int(counts.max())
    if low < 0 or high >= ROUNDED_TABLE_MOST:
        plain: Int64Array = np.rint(counts * char_time_ns).astype(np.int64)
        return plain
    table = _ROUNDED.get(char_time_ns)
    if table is None or len(table) <= high:
        size = min(max(high + 1, 256, 2 * len(table) if table is not None else 0), ROUNDED_TABLE_MOST)
        table = _ROUNDED[char_time_ns] = np.rint(np.arange(size, dtype=np.int64) * char_time_ns).astype(np.int64)
    rounded: Int64Array = table.take(counts)
    return rounded


@dataclass(frozen=True)
class ByteClock:
    """The wire times of a run of bytes, kept per chunk as the capture gives them.

    The framer asks for few byte times (the first and last bytes of frames, the silences
    between chunks) of many bytes: computing all of them (:func:`byte_times`) cost it a
    quarter of its time on the benchmark captures, eleven bytes a chunk. The times are those of
    :func:`byte_times`, byte for byte, and inside a chunk the silence between two bytes is
    exactly zero, so every silence of the run lies where one chunk ends and the next begins.

    ``ends[k]``: one past chunk *k*'s last byte (from the run's first byte, increasing: no
    chunk is empty); ``t_end_ns[k]``: when that byte ended.
    """

    ends: Int64Array
    t_end_ns: Int64Array
    char_time_ns: float

    @classmethod
    def of(cls, batch: ChunkBatch, char_time_ns: float) -> ByteClock:
        """The clock of ``batch``'s bytes (its empty chunks, which time no byte, left out)."""
        filled = np.diff(batch.ends, prepend=0) > 0
        if filled.all():
            return cls(batch.ends, batch.t_end_ns, char_time_ns)
        return cls(batch.ends[filled], batch.t_end_ns[filled], char_time_ns)

    @classmethod
    def empty(cls, char_time_ns: float) -> ByteClock:
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), char_time_ns)

    def __len__(self) -> int:
        return int(self.ends[-1]) if len(self.ends) else 0

    def then(self, later: ByteClock) -> ByteClock:
        """This run followed by ``later``'s bytes."""
        if not len(self.ends):
            return later
        return ByteClock(np.concatenate([self.ends, later.ends + len(self)]),
                         np.concatenate([self.t_end_ns, later.t_end_ns]), self.char_time_ns)

    def tail(self, begin: int) -> ByteClock:
        """The bytes from ``begin`` on (a byte's time is counted from its chunk's end: it stays)."""
        kept = self.ends > begin
        return ByteClock(self.ends[kept] - begin, self.t_end_ns[kept], self.char_time_ns)

    def _before_end(self, chunks: Int64Array, positions: Int64Array, chars: int) -> Int64Array:
        """The time ``chars`` characters after the start of each byte ``positions[i]`` of chunk
        ``chunks[i]``: counted back from the chunk's end, rounded as :func:`byte_times` rounds."""
        to_end = self.ends[chunks] - positions - chars
        times: Int64Array = self.t_end_ns[chunks] - rounded_char_times(to_end, self.char_time_ns)
        return times

    def starts_at(self, positions: Int64Array) -> Int64Array:
        """When the start bit of each byte ``positions[i]`` began."""
        return self._before_end(np.searchsorted(self.ends, positions, side="right"), positions, 0)

    def ends_at(self, positions: Int64Array) -> Int64Array:
        """When the stop bit of each byte ``positions[i]`` ended."""
        return self._before_end(np.searchsorted(self.ends, positions, side="right"), positions, 1)

    def run_times(self, starts: Int64Array, stops: Int64Array,
                  chunks: Int64Array | None = None) -> tuple[Int64Array, Int64Array]:
        """Start of the first byte and end of the last of each run ``[starts[i], stops[i])``
        of bytes of one chunk (``chunks``: each run's chunk, where the caller knows them)."""
        if chunks is None:
            chunks = np.searchsorted(self.ends, starts, side="right")
        # :meth:`_before_end` of the first bytes (0 characters after their start) and of the last
        # (1 after), the chunks' ends and times gathered once for both.
        chunk_ends, chunk_times = self.ends[chunks], self.t_end_ns[chunks]
        first: Int64Array = chunk_times - rounded_char_times(chunk_ends - starts, self.char_time_ns)
        last: Int64Array = chunk_times - rounded_char_times(chunk_ends - stops, self.char_time_ns)
        return first, last

    def piece_times(self, chunk_starts: Int64Array, first: Int64Array,
                    starts_piece: npt.NDArray[np.bool_]) -> tuple[Int64Array, Int64Array]:
        """Earliest start and latest end of the bytes of each piece ``[first[i], first[i+1])`` (the
        last up to the end of ``starts_piece``, which marks the bytes ``first`` holds; ``chunk_starts``:
        where chunks begin, sorted): the times of its first and last bytes on a consistent capture,
        and still ordered on one whose times overlap. Inside a chunk times only grow, so each run of
        a piece's bytes in one chunk gives its first byte's start and its last byte's end."""
        stop = len(starts_piece) - 1
        inside = chunk_starts[(chunk_starts > first[0]) & (chunk_starts < stop)]
        # Mostly a chunk is a frame: few chunks begin inside a piece.
        extra = inside[~starts_piece[inside]]
        piece_ends = _run_ends(first, stop)
        chunks = self._piece_chunks(first, inside, extra)
        if not len(extra):
            return self.run_times(first, piece_ends, chunks)
        # A piece's first run ends where the first chunk inside it begins; the runs of those
        # chunks (few) are timed apart, and their times folded into their pieces'.
        holder = np.searchsorted(first, extra) - 1
        first_inside = np.ones(len(extra), np.bool_)
        first_inside[1:] = holder[1:] != holder[:-1]
        first_run_ends = piece_ends.copy()
        first_run_ends[holder[first_inside]] = extra[first_inside]
        t_start, t_end = self.run_times(first, first_run_ends, chunks)
        extra_ends = np.minimum(_run_ends(extra, stop), piece_ends[holder])
        extra_starts, extra_stops = self.run_times(extra, extra_ends)
        np.minimum.at(t_start, holder, extra_starts)
        np.maximum.at(t_end, holder, extra_stops)
        return t_start, t_end

    def _piece_chunks(self, first: Int64Array, inside: Int64Array, extra: Int64Array) -> Int64Array | None:
        """The chunk of each piece's first byte where every piece but the first begins a chunk
        (mostly a frame is a chunk): from the first piece's chunk, one more a piece and one
        more for each chunk beginning inside a piece before it (``extra``, of the chunks
        beginning ``inside`` the pieces), faster than searching every frame's chunk. ``None``
        where a piece begins inside a chunk."""
        if len(inside) - len(extra) != len(first) - 1:
            return None
        chunks: Int64Array = np.cumsum(np.bincount(np.searchsorted(first, extra), minlength=len(first))[: len(first)])
        chunks += np.arange(len(first), dtype=np.int64) + int(np.searchsorted(self.ends, first[0], side="right"))
        return chunks

    def silences(self) -> tuple[Int64Array, Int64Array]:
        """Where each chunk but the first begins (byte positions, in order) and the silence
        before it, in ns: every silence of the run that is not zero."""
        positions = self.ends[:-1]
        later = np.arange(1, len(self.ends), dtype=np.int64)
        return positions, self._before_end(later, positions, 0) - self.t_end_ns[:-1]


def _run_ends(runs: Int64Array, stop: int) -> Int64Array:
    """Where each run of bytes starting at ``runs`` ends: at the next, the last at ``stop``."""
    ends = np.empty_like(runs)
    ends[:-1] = runs[1:]
    ends[-1] = stop
    return ends
