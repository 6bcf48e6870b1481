"""The ``latencies`` table's histograms: every answered request counted once, in the bin that
holds its latency, by day, slave and function (USS telegrams have none), however the
transactions come in batches (binned by :func:`latency_bins`, as the decoding process does)."""

from __future__ import annotations

from collections import Counter
from itertools import pairwise

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.message import NONE
from sniffer.exports.latency_bins import DAY_NS, latency_bins
from sniffer.exports.parquet_latencies import LatencyHistograms
from sniffer.exports.transactions import OUTCOMES

TRANSACTIONS = st.lists(st.tuples(
    st.one_of(st.sampled_from([-5, 0, 7, DAY_NS + 3]), st.integers(-2 * DAY_NS, 3 * DAY_NS)),  # t_ns, 1969 too
    st.sampled_from([NONE, 0, 1, 17, 247, 255]),  # slave
    st.sampled_from([NONE, 1, 3, 16, 43, 255]),  # function
    st.integers(0, len(OUTCOMES) - 1),
    st.one_of(st.integers(0, 5_000), st.integers(5_000, 2_000_000_000), st.just(NONE)),  # latency ns
), max_size=60)


@settings(max_examples=300, deadline=None)
@given(TRANSACTIONS, st.lists(st.integers(0, 60), max_size=3))
def test_every_answer_is_counted_once_in_its_bin(transactions: list[tuple[int, ...]], cuts: list[int]) -> None:
    histograms = LatencyHistograms()
    bounds = [0, *sorted(cut for cut in set(cuts) if 0 < cut < len(transactions)), len(transactions)]
    for start, stop in pairwise(bounds):
        part = np.array(transactions[start:stop], np.int64).reshape(-1, 5)
        histograms.add(*latency_bins({"t_ns": part[:, 0], "slave": part[:, 1], "function": part[:, 2],
                                      "outcome": part[:, 3], "latency_ns": part[:, 4]}))
    t_ns, columns = histograms.columns()
    rows = list(zip(t_ns.tolist(), *(columns[name].to_pylist() for name in
                                      ("slave", "function", "from_ms", "to_ms", "answers")), strict=True))
    counted: Counter[tuple[object, ...]] = Counter()
    for day_ns, slave, function, _, _, answers in rows:
        counted[(day_ns // DAY_NS, slave, function)] += answers
    answered = [row for row in transactions if OUTCOMES[row[3]] == "answered"]
    expected = Counter((t // DAY_NS, None if slave == NONE else slave, None if function == NONE else function)
                       for t, slave, function, _, _ in answered)
    assert counted == expected
    for t, slave, function, _, latency in answered:
        key = (t // DAY_NS * DAY_NS, None if slave == NONE else slave, None if function == NONE else function)
        bins = [row for row in rows if row[:3] == key and row[3] <= max(latency, 1) / 1e6 * 1.000001
                and max(latency, 1) / 1e6 < row[4] * 1.000001]
        assert bins, (key, latency)
    assert rows == sorted(rows, key=lambda row: (row[0], row[1] if row[1] is not None else -1,
                                                 row[2] if row[2] is not None else -1, row[3]))


@settings(max_examples=200, deadline=None)
@given(TRANSACTIONS, st.integers(1, 3))
def test_batches_of_bins_already_held_add_to_them(transactions: list[tuple[int, ...]], repeats: int) -> None:
    """A batch whose every bin is held already (the usual batch of a running bus) adds its counts
    to theirs: the same transactions ``repeats`` more times count ``repeats`` more times."""
    part = np.array(transactions, np.int64).reshape(-1, 5)
    once, again = LatencyHistograms(), LatencyHistograms()
    for histograms, times in ((once, 1), (again, 1 + repeats)):
        for _ in range(times):
            histograms.add(*latency_bins({"t_ns": part[:, 0], "slave": part[:, 1], "function": part[:, 2],
                                          "outcome": part[:, 3], "latency_ns": part[:, 4]}))
    (t_once, first), (t_again, more) = once.columns(), again.columns()
    assert t_again.tolist() == t_once.tolist()
    assert more["answers"].to_pylist() == [(1 + repeats) * count for count in first["answers"].to_pylist()]
    assert all(more[name].equals(first[name]) for name in ("slave", "function", "from_ms", "to_ms"))
