"""Quantities over time in a fixed number of buckets, for charts of a capture of any length.

A :class:`Timeline` holds ``buckets`` equal time buckets from the first time it is given,
each ``width_ns`` wide. When a time falls past the last bucket, neighbouring buckets merge in
pairs and the width doubles, until it fits: memory stays fixed whatever the capture's length,
every bucket covers the same span, and nothing added is ever lost (a count merged is a count
kept). Each series says how its buckets merge:

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
        series = self.series.get(name)
        if series is None:
            series = self.series[name] = Series(merge, _empty(merge, self.buckets))
        elif series.merge != merge:
            raise ValueError(f"series {name!r} merges by {series.merge}, not {merge}")
        if not len(t_ns):
            return
        where = self._buckets(t_ns)
        data = np.ones(len(where)) if values is None else np.asarray(values, np.float64)
        if merge == "sum":
            np.add.at(series.values, where, data)
        elif merge == "max":
            np.fmax.at(series.values, where, data)
        elif merge == "min":
            np.fmin.at(series.values, where, data)
        else:  # the last one given of each bucket (fancy assignment does not promise an order)
            buckets, first_from_end = np.unique(where[::-1], return_index=True)
            series.values[buckets] = data[len(where) - 1 - first_from_end]

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
            self.origin_ns = int(t_ns.min())
        top = int(t_ns.max()) - self.origin_ns
        while top >= self.buckets * self.width_ns:
            self._widen()
        where = np.maximum(t_ns - self.origin_ns, 0) // self.width_ns
        self.used = max(self.used, int(where.max()) + 1)
        return where

    def _widen(self) -> None:
        """Merge neighbouring buckets in pairs: twice the width, the second half empty."""
        half = self.buckets // 2
        for series in self.series.values():
            pairs = series.values.reshape(half, 2)
            merged = _merge_pairs(series.merge, pairs)
            series.values = np.concatenate([merged, _empty(series.merge, half)])
        self.width_ns *= 2
        self.used = (self.used + 1) // 2

    def values(self, name: str) -> npt.NDArray[np.float64]:
        """The used buckets of ``name`` (empty ones NaN, or 0 for a sum)."""
        return self.series[name].values[: self.used]



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
