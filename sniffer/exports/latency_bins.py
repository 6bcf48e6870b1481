"""The answered requests of a batch binned for the Parquet ``latencies`` table
(:mod:`sniffer.exports.parquet_latencies`), in the decoding process.

The Parquet sink's ``prepare`` (run where the batch is decoded, :mod:`sniffer.decoding_process`)
adds each batch's bins and their counts to its transactions' columns, so that the thread that
annotates and writes only merges a few hundred bins a batch, not the sort that finds them. No
pyarrow here: the decoding process never imports it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.stats import HISTOGRAM_BINS, histogram_bins
from sniffer.exports.transactions import OUTCOMES

#: Nanoseconds of a UTC day: the dataset's date partitions, the histograms' days.
DAY_NS = 86_400 * 1_000_000_000
_ANSWERED = OUTCOMES.index("answered")


def latency_bins(transactions: dict[str, npt.NDArray[np.int64]]) -> tuple[npt.NDArray[np.int64],
                                                                           npt.NDArray[np.int64]]:
    """The bins (:func:`bin_keys`, ascending) the answered ones of ``transactions`` (as
    :meth:`~sniffer.exports.transactions.TransactionEncoder.columns` gives them) fall in, and how
    many fall in each."""
    answered = np.flatnonzero(transactions["outcome"] == _ANSWERED)
    keys = bin_keys(transactions["t_ns"][answered] // DAY_NS, transactions["slave"][answered],
                    transactions["function"][answered], histogram_bins(transactions["latency_ns"][answered]))
    found, counts = np.unique(keys, return_counts=True)
    return found.astype(np.int64), counts.astype(np.int64)


def bin_keys(days: npt.NDArray[np.int64], slaves: npt.NDArray[np.int64], functions: npt.NDArray[np.int64],
             bins: npt.NDArray[np.intp]) -> npt.NDArray[np.int64]:
    """Day, slave, function and bin as one number that sorts as they do. Slave and function are
    0..255, or NONE (a USS telegram has no function): 9 bits each once one is added."""
    keys: npt.NDArray[np.int64] = ((days * 512 + slaves + 1) * 512 + functions + 1) * HISTOGRAM_BINS + bins
    return keys
