"""Quantities over time in a fixed number of buckets, for charts of a capture of any length.

A :class:`Timeline` holds ``buckets`` equal time buckets, each ``width_ns`` wide, from the
first time it is given rounded down to a multiple of the width (from the epoch). When a time
falls past the last bucket, neighbouring buckets merge in pairs and the width doubles, until it
fits: memory stays fixed whatever the capture's length, every bucket covers the same span, and
nothing added is ever lost (a count merged is a count kept).

Bucket edges are multiples of the width since the epoch, and widths are the first width times
a power of two: a bucket of one timeline lies inside exactly one bucket of any wider one. So
the timelines of separate captures (``report --each``) merge exactly (:meth:`Timeline.merge`):
the result is what one timeline given every time would hold. Each series says how its buckets
merge:

* ``sum`` (counts, wire time): added;
* ``max`` and ``min``: the larger and the smaller;
* ``last`` (a value as it stood): the later bucket's, where it has one.

Empty buckets are NaN for ``max``, ``min`` and ``last``, 0 for ``sum``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

Merge = Literal["sum", "max", "min", "last"]
#: Buckets of a report's charts: an hour is 5 s buckets, a day 2 minutes.
BUCKETS = 1000
#: The first width: 10 ms, widened as the capture goes on.
FIRST_WIDTH_NS = 10_000_000


@dataclass
class Series:
    merge: Merge
    values: npt.NDArray[np.float64]


class Timeline:
    """Series of buckets over one time axis (see the module docstring)."""

    def __init__(self, buckets: int = BUCKETS, width_ns: int = FIRST_WIDTH_NS) -> None:
        if buckets < 2 or buckets % 2:
            raise ValueError("a timeline needs an even number of buckets, at least 2")
        self.buckets = buckets
        self.width_ns = width_ns
        self.origin_ns: int | None = None
        #: Buckets up to the last one given a value (the rest of the axis is still empty).
        self.used = 0
        self.series: dict[str, Series] = {}

    def add(self, name: str, merge: Merge, t_ns: npt.NDArray[np.int64],
            values: npt.NDArray[np.float64] | None = None) -> None:
        """Add ``values`` (1 each when ``None``: a count) at times ``t_ns`` to the series ``name``."""
        series = self._series(name, merge)
        if not len(t_ns):
            return
        where = self._buckets(t_ns)
        _put(series, where, np.ones(len(where)) if values is None else np.asarray(values, np.float64))

    def _series(self, name: str, merge: Merge) -> Series:
        series = self.series.get(name)
        if series is None:
            series = self.series[name] = Series(merge, _empty(merge, self.buckets))
        elif series.merge != merge:
            raise ValueError(f"series {name!r} merges by {series.merge}, not {merge}")
        return series

    def merge(self, other: Timeline) -> None:
        """Add ``other``'s buckets (another capture's, same number of buckets): exactly, as if
        every time given to it had been given to this one. A ``last`` bucket takes ``other``'s
        value where it has one: merge captures in time order."""
        if other.buckets != self.buckets:
            raise ValueError(f"a timeline of {other.buckets} buckets does not merge into one of {self.buckets}")
        for name, theirs in other.series.items():
            self._series(name, theirs.merge)
        if other.origin_ns is None or not other.used:
            return
        while self.width_ns < other.width_ns:
            self._widen()
        starts = other.origin_ns + np.arange(other.used, dtype=np.int64) * other.width_ns
        if self.origin_ns is not None:
            self._start_at(int(starts[0]))
        self._buckets(starts[[0, -1]])  # the origin (this one empty) and the width that holds both
        assert self.origin_ns is not None
        where = (starts - self.origin_ns) // self.width_ns
        for name, theirs in other.series.items():
            _put(self.series[name], where, theirs.values[: other.used], skip_empty=True)

    def _start_at(self, t_ns: int) -> None:
        """Move the origin back to hold ``t_ns`` (a capture earlier than the ones merged so far),
        widening while the buckets used would not fit."""
        assert self.origin_ns is not None
        while True:
            origin = t_ns - t_ns % self.width_ns
            shift = (self.origin_ns - origin) // self.width_ns
            if shift <= 0:
                return
            if self.used + shift <= self.buckets:
                break
            self._widen()
        for series in self.series.values():
            series.values = np.concatenate([_empty(series.merge, shift), series.values[: self.buckets - shift]])
        self.origin_ns, self.used = origin, self.used + shift

    def add_spans(self, name: str, t_start_ns: npt.NDArray[np.int64], t_end_ns: npt.NDArray[np.int64]) -> None:
        """Add the time each span [start, end) covers of each bucket to the sum series ``name``
        (a frame's wire time: a bucket never holds more than its width of it)."""
        if not len(t_start_ns):
            self.add(name, "sum", t_start_ns)
            return
        ends = np.maximum(t_end_ns - 1, t_start_ns)  # the last nanosecond each span covers
        self._buckets(t_start_ns)  # the origin, where there is none yet: the first start
        self._buckets(ends)  # widen for the spans' ends first: the buckets below are final
        first, last = self._buckets(t_start_ns), self._buckets(ends)
        inside = first == last
        self.add(name, "sum", t_start_ns[inside], (t_end_ns - t_start_ns)[inside].astype(np.float64))
        assert self.origin_ns is not None
        for start, end in zip(t_start_ns[~inside].tolist(), t_end_ns[~inside].tolist(), strict=True):
            origin, width = self.origin_ns, self.width_ns
            edges = np.arange((start - origin) // width + 1, (end - 1 - origin) // width + 1)
            cuts = np.concatenate([[start], self.origin_ns + edges * self.width_ns, [end]])
            self.add(name, "sum", cuts[:-1], np.diff(cuts).astype(np.float64))

    def _buckets(self, t_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        if self.origin_ns is None:
            first = int(t_ns.min())
            self.origin_ns = first - first % self.width_ns
        last = int(t_ns.max())
        while last - self.origin_ns >= self.buckets * self.width_ns:  # widening may move the origin back
            self._widen()
        where = np.maximum(t_ns - self.origin_ns, 0) // self.width_ns
        self.used = max(self.used, int(where.max()) + 1)
        return where

    def _widen(self) -> None:
        """Merge neighbouring buckets in pairs: twice the width, the second half empty. Pairs
        start at multiples of the new width: where the origin is an odd multiple of the old one,
        the first bucket pairs with an empty one before it."""
        odd = 0 if self.origin_ns is None else (self.origin_ns // self.width_ns) % 2
        for series in self.series.values():
            values = series.values
            if odd:
                values = np.concatenate([_empty(series.merge, 1), values, _empty(series.merge, 1)])
            merged = _merge_pairs(series.merge, values.reshape(-1, 2))
            series.values = np.concatenate([merged, _empty(series.merge, self.buckets - len(merged))])
        if self.origin_ns is not None:
            self.origin_ns -= odd * self.width_ns
        self.width_ns *= 2
        self.used = (self.used + odd + 1) // 2

    def values(self, name: str) -> npt.NDArray[np.float64]:
        """The used buckets of ``name`` (empty ones NaN, or 0 for a sum)."""
        return self.series[name].values[: self.used]



def _put(series: Series, where: npt.NDArray[np.int64], data: npt.NDArray[np.float64], *,
         skip_empty: bool = False) -> None:
    """Add ``data`` at buckets ``where`` as the series merges (``skip_empty``: NaN is no value)."""
    merge = series.merge
    if merge == "sum":
        np.add.at(series.values, where, data)
    elif merge == "max":
        np.fmax.at(series.values, where, data)
    elif merge == "min":
        np.fmin.at(series.values, where, data)
    else:  # the last one given of each bucket (fancy assignment does not promise an order)
        if skip_empty:
            given = ~np.isnan(data)
            where, data = where[given], data[given]
        buckets, first_from_end = np.unique(where[::-1], return_index=True)
        series.values[buckets] = data[len(where) - 1 - first_from_end]


def _empty(merge: Merge, length: int) -> npt.NDArray[np.float64]:
    return np.zeros(length) if merge == "sum" else np.full(length, np.nan)


def _merge_pairs(merge: Merge, pairs: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    first, second = pairs[:, 0], pairs[:, 1]
    if merge == "sum":
        return first + second
    if merge == "max":
        return np.fmax(first, second)
    if merge == "min":
        return np.fmin(first, second)
    return np.where(np.isnan(second), first, second)
