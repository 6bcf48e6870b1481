"""The per slave and function figures of :class:`decoders.stats.Statistics`, gathered in arrays.

A batch of 8 192 frames touches every pair of slave and function of a bus; added to their
:class:`~decoders.stats.FunctionStats` one by one, each batch cost a Python step per pair and
counter and a histogram merge per pair (a quarter of ``stats``'s time on a bus of many pairs).
Here a batch adds to arrays with a row per pair: its counters, its two
histograms (latency, poll period) and their exact minima and maxima, by numpy. The statistics
take the rows out (:meth:`FunctionTally.drain`, then :meth:`FunctionTally.clear`) when they are
read, which is far less often than batches come.

Memory: a pair's two histograms take 2 × 2 084 counts here as in its ``FunctionStats``; held
as 32-bit counts (the statistics take the rows out before 2**31 values are held:
:attr:`FunctionTally.held`), they add half of what the objects take (17 MB on a bus of 1 000
pairs).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct

Number = TypeVar("Number", bound=np.integer)
#: A pair's key: ``slave * KEY_SPAN + function`` (both 0..255).
KEY_SPAN = 256
_NO_ROW = -1
_FIRST_ROWS = 16
#: Histograms the tally keeps per pair (:data:`LATENCY`, :data:`POLL_PERIOD`).
LATENCY, POLL_PERIOD = 0, 1
_EMPTY_LOW, _EMPTY_HIGH = np.iinfo(np.int64).max, np.iinfo(np.int64).min
#: Histogram cells (pairs × bins) per value up to which a batch's values are counted into every
#: cell rather than sorted (``bincount`` of 64 k cells took the time ``unique`` of 12 k values took
#: twice over).
DENSE_CELLS_PER_VALUE = 16


@dataclass
class TalliedHistogram:
    """One histogram's rows of a pair since the last drain: binned counts (a view into the
    tally, valid until :meth:`FunctionTally.clear`), how many, exact bounds."""

    counts: npt.NDArray[np.int32]
    count: int
    low: int
    high: int


@dataclass
class TalliedFunction:
    """What a pair of slave and function gathered since the last drain."""

    slave: int
    function: int
    counters: list[int]
    exceptions: Counter[int]
    histograms: tuple[TalliedHistogram | None, TalliedHistogram | None]


class FunctionTally:
    """Counters and histograms per pair of slave and function, a row each, in arrays."""

    def __init__(self, counters: int, bins: int) -> None:
        """``counters``: how many counters a pair has; ``bins``: how many bins a histogram has."""
        self._bins = bins
        # Nothing is allocated before the first batch: statistics sent back by another process
        # to be merged (drained, :meth:`decoders.stats.Statistics.portable`) pickle small.
        self._row_of = np.zeros(0, np.int64)
        self._keys: list[int] = []
        self._counts = np.zeros((0, counters), np.int64)
        self._histograms = np.zeros((2, 0, bins), np.int32)
        self._sizes = np.zeros((2, 0), np.int64)
        self._lows = np.zeros((2, 0), np.int64)
        self._highs = np.zeros((2, 0), np.int64)
        self._exceptions: Counter[tuple[int, int]] = Counter()
        #: The rows of the keys given since the last drain (a pair appears even with nothing counted).
        self._seen = np.zeros(0, np.bool_)
        #: Values held in the histograms since the last clear: no bin holds more.
        self.held = 0

    def rows(self, keys: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        """The row of each key; keys new to the tally get new rows, in ascending order (so rows
        are in the order :class:`~decoders.stats.Statistics` first met their pairs in)."""
        if not len(self._row_of):
            self._row_of = np.full(KEY_SPAN * KEY_SPAN, _NO_ROW, np.int64)
        rows = self._row_of[keys]
        unknown = rows == _NO_ROW
        if unknown.any():
            new = distinct(keys[unknown])
            first = len(self._keys)
            self._grow(first + len(new))
            self._row_of[new] = np.arange(first, first + len(new))
            self._keys.extend(new.tolist())
            rows = self._row_of[keys]
        self._seen[rows] = True
        return rows

    def count(self, rows: npt.NDArray[np.int64], counted: list[npt.NDArray[np.bool_]]) -> None:
        """Counter ``c`` of the pair at ``rows[k]`` grows by one where ``counted[c][k]``."""
        used = len(self._keys)
        for counter, mask in enumerate(counted):
            self._counts[:used, counter] += np.bincount(rows[mask], minlength=used)

    def add(self, histogram: int, rows: npt.NDArray[np.int64], bins: npt.NDArray[np.intp],
            values: npt.NDArray[np.int64]) -> None:
        """``values`` (binned as ``bins``) into ``histogram`` of the pair at each one's row."""
        if not len(values):
            return
        # By counting and sorting, not ufunc.at: that costs 45 ns a value, four times what these steps take.
        self.held += len(values)
        used = len(self._keys)
        cells = rows * self._bins + bins
        if used * self._bins <= DENSE_CELLS_PER_VALUE * len(values):
            # Few pairs for many values (a polled bus): counting every cell beats sorting the values.
            counted = np.bincount(cells, minlength=used * self._bins).astype(np.int32)
            self._histograms[histogram, :used] += counted.reshape(used, self._bins)
        else:
            cells, counts = np.unique(cells, return_counts=True)
            self._histograms[histogram].reshape(-1)[cells] += counts.astype(np.int32)  # a view: it is contiguous
        # Rows are below KEY_SPAN**2 (a row per pair): as 16-bit keys numpy sorts them stably by radix.
        order = np.argsort(rows.astype(np.uint16), kind="stable")
        rows, values = rows[order], values[order]
        starts = np.flatnonzero(np.diff(rows, prepend=-1))
        which = rows[starts]
        self._sizes[histogram, which] += np.diff(np.append(starts, len(rows)))
        self._lows[histogram, which] = np.minimum(self._lows[histogram, which], np.minimum.reduceat(values, starts))
        self._highs[histogram, which] = np.maximum(self._highs[histogram, which], np.maximum.reduceat(values, starts))

    def add_exceptions(self, rows: npt.NDArray[np.int64], codes: npt.NDArray[np.int64]) -> None:
        """An exception answer with ``codes[k]`` for the pair at ``rows[k]``."""
        self._exceptions.update(zip(rows.tolist(), codes.tolist(), strict=True))

    def drain(self) -> list[TalliedFunction]:
        """Every pair given since the last clear, in the order of their rows, with what it
        gathered (its histograms' counts are views: take them before :meth:`clear`)."""
        used = len(self._keys)
        exceptions: dict[int, Counter[int]] = {}
        for (row, code), times in self._exceptions.items():
            exceptions.setdefault(row, Counter())[code] += times
        return [
            TalliedFunction(*divmod(self._keys[row], KEY_SPAN), self._counts[row].tolist(),
                            exceptions.get(row, Counter()),
                            (self._histogram(LATENCY, row), self._histogram(POLL_PERIOD, row)))
            for row in np.flatnonzero(self._seen[:used]).tolist()
        ]

    def clear(self) -> None:
        """The tally afresh (its rows kept for the pairs it knows). Only the rows given since
        the last clear hold anything: clearing those alone keeps a bus of thousands of pairs
        from clearing megabytes for each batch (compare of two such captures took minutes)."""
        seen = np.flatnonzero(self._seen[: len(self._keys)])
        self._counts[seen] = 0
        self._histograms[:, seen] = 0
        self._sizes[:, seen] = 0
        self._lows[:, seen], self._highs[:, seen] = _EMPTY_LOW, _EMPTY_HIGH
        self._exceptions.clear()
        self._seen[seen] = False
        self.held = 0

    def _histogram(self, histogram: int, row: int) -> TalliedHistogram | None:
        size = int(self._sizes[histogram, row])
        if not size:
            return None
        return TalliedHistogram(self._histograms[histogram, row], size, int(self._lows[histogram, row]),
                                int(self._highs[histogram, row]))

    def _grow(self, rows: int) -> None:
        """Room for ``rows`` rows (doubling, so that a bus's pairs cost a few copies in all)."""
        have = len(self._counts)
        if rows <= have:
            return
        size = max(rows, 2 * have, _FIRST_ROWS)
        self._counts = _grown(self._counts, size, 0)
        self._histograms = _grown(self._histograms, size, 0, axis=1)
        self._sizes = _grown(self._sizes, size, 0, axis=1)
        self._lows = _grown(self._lows, size, _EMPTY_LOW, axis=1)
        self._highs = _grown(self._highs, size, _EMPTY_HIGH, axis=1)
        seen = np.zeros(size, np.bool_)
        seen[:have] = self._seen
        self._seen = seen


def _grown(array: npt.NDArray[Number], size: int, fill: int, axis: int = 0) -> npt.NDArray[Number]:
    shape = list(array.shape)
    shape[axis] = size
    grown = np.full(shape, fill, array.dtype)
    grown[tuple(slice(0, n) for n in array.shape)] = array
    return grown
