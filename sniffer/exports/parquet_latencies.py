"""The Parquet ``latencies`` table: the latencies of answered requests as histograms, a row per
bin that holds any, by bus and date (the partitions), slave and function.

An exact percentile over a plant's ``transactions`` reads every answer. The same question over
these histograms reads a few thousand rows per capture and day (the figures, from
``benchmarks.bench_plant``: ``docs/performance.md``). Their bins are
those of ``rtusniff stats`` (:mod:`decoders.stats`: logarithmic, 1 % wide, 1 µs to 1000 s), so a
percentile read from them is within 1 % of the exact one, as ``stats`` says it; histograms of many
captures, buses or days merge by adding their counts. A row: ``slave``, ``function``, the bin
(``from_ms`` up to ``to_ms``) and how many ``answers`` fell in it; answers are counted where the
``transactions`` table has them ``answered``, at their transaction's date.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.stats import HISTOGRAM_BINS, bin_floor_ns
from sniffer.exports.latency_bins import DAY_NS
from sniffer.exports.parquet_export import nullable

#: Each bin's bounds in milliseconds (the last holds everything above its floor).
_FROM_MS = bin_floor_ns(np.arange(HISTOGRAM_BINS, dtype=np.int64)) / 1e6
_TO_MS = np.append(_FROM_MS[1:], np.inf)


class LatencyHistograms:
    """The answers' latencies of one capture, binned by day, slave and function: only the bins
    that hold any are kept (a histogram has 2 084 bins; a drive's answers fill a few dozen)."""

    def __init__(self) -> None:
        #: Each bin held, by one number (:func:`~sniffer.exports.latency_bins.bin_keys`), ascending,
        #: and its count.
        self._keys = np.zeros(0, np.int64)
        self._counts = np.zeros(0, np.int64)

    def add(self, found: npt.NDArray[np.int64], counts: npt.NDArray[np.int64]) -> None:
        """Bins of a batch and their counts, as :func:`~sniffer.exports.latency_bins.latency_bins`
        gives them."""
        if not len(found):
            return
        self._keys, where = np.unique(np.concatenate([self._keys, found]), return_inverse=True)
        merged = np.zeros(len(self._keys), np.int64)
        np.add.at(merged, where, np.concatenate([self._counts, counts]))
        self._counts = merged

    def columns(self) -> tuple[npt.NDArray[np.int64], dict[str, pa.Array]]:
        """The table's rows (each one's time: the start of its day), by day, slave, function, bin."""
        keys, bins = np.divmod(self._keys, HISTOGRAM_BINS)
        keys, function = np.divmod(keys, 512)
        day, slave = np.divmod(keys, 512)
        return day * DAY_NS, {
            "slave": nullable(slave - 1, pa.int16()),
            "function": nullable(function - 1, pa.int16()),
            "from_ms": pa.array(_FROM_MS[bins], pa.float64()),
            "to_ms": pa.array(_TO_MS[bins], pa.float64()),
            "answers": pa.array(self._counts, pa.int64()),
        }

