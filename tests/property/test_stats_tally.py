"""Hypothesis: the tally of the statistics (:mod:`decoders.stats_tally`) adds up what it is
given, pair by pair, as plain Python counting does, however its batches are cut and however
often it is drained (a live view reads the statistics every second); and the statistics read
in the middle of a capture end as those read once at its end, on buses of many pairs (the
tally grows its rows)."""

from __future__ import annotations

from collections import Counter
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders import stats, stats_tally
from decoders.message import MessageBatch
from decoders.stats import Statistics
from decoders.stats_tally import KEY_SPAN, LATENCY, POLL_PERIOD, FunctionTally, TalliedFunction
from tests.property.test_statistics_splits import _COLUMNS, _slice, whole_capture

BINS = 50
COUNTERS = 3

_message = st.tuples(
    st.integers(0, 255), st.sampled_from([1, 3, 6, 16, 255]),  # slave, function
    st.lists(st.booleans(), min_size=COUNTERS, max_size=COUNTERS),  # which counters it counts in
    st.none() | st.integers(0, 10**12),  # a latency
    st.none() | st.integers(0, 10**12),  # a poll period
    st.none() | st.integers(1, 11),  # an exception code
)


def _bin(value: int) -> int:
    return min(value.bit_length(), BINS - 1)


def _plain(messages: list[tuple]) -> dict[tuple[int, int], tuple]:  # type: ignore[type-arg]
    """What each pair gathered, counted one message at a time."""
    pairs: dict[tuple[int, int], tuple] = {}  # type: ignore[type-arg]
    for slave, function, counted, latency, period, code in messages:
        counters, exceptions, histograms = pairs.setdefault(
            (slave, function), ([0] * COUNTERS, Counter(), ([], [])))
        for index, flag in enumerate(counted):
            counters[index] += flag
        if code is not None:
            exceptions[code] += 1
        for values, value in zip(histograms, (latency, period), strict=True):
            if value is not None:
                values.append(value)
    return pairs


def _summed(drains: list[list[TalliedFunction]]) -> dict[tuple[int, int], tuple]:  # type: ignore[type-arg]
    """The drains of a tally added up, as the statistics add them."""
    pairs: dict[tuple[int, int], tuple] = {}  # type: ignore[type-arg]
    for drained in drains:
        for tallied in drained:
            counters, exceptions, histograms = pairs.setdefault(
                (tallied.slave, tallied.function),
                ([0] * COUNTERS, Counter(), tuple([np.zeros(BINS, np.int64), 0, None, None] for _ in range(2))))
            for index, grown in enumerate(tallied.counters):
                counters[index] += grown
            exceptions.update(tallied.exceptions)
            for mine, gathered in zip(histograms, tallied.histograms, strict=True):
                if gathered is not None:
                    mine[0] = mine[0] + gathered.counts
                    mine[1] += gathered.count
                    mine[2] = gathered.low if mine[2] is None else min(mine[2], gathered.low)
                    mine[3] = gathered.high if mine[3] is None else max(mine[3], gathered.high)
    return pairs


def _taken(tally: FunctionTally) -> list[TalliedFunction]:
    """What the tally drains, its counts copied before it is cleared (they are views)."""
    drained = tally.drain()
    for tallied in drained:
        for histogram in tallied.histograms:
            if histogram is not None:
                histogram.counts = histogram.counts.copy()
    tally.clear()
    return drained


#: A tally's histograms counted cell by cell for every batch, and by sorting its values for every batch.
_BOTH_WAYS = pytest.mark.parametrize("cells_per_value", [10**9, 0], ids=["counted", "sorted"])


@_BOTH_WAYS
@settings(max_examples=150, deadline=None)
@given(st.lists(_message, max_size=300), st.lists(st.integers(1, 60), min_size=1, max_size=10),
       st.lists(st.booleans(), min_size=1, max_size=10))
def test_the_tally_adds_up_as_plain_counting(cells_per_value: int, messages: list[tuple],  # type: ignore[type-arg]
                                             sizes: list[int], drains_after: list[bool]) -> None:
    with mock.patch.object(stats_tally, "DENSE_CELLS_PER_VALUE", cells_per_value):
        _tallied_as_plain(messages, sizes, drains_after)


@_BOTH_WAYS
def test_a_bus_of_thousands_of_pairs_adds_up_as_plain_counting(cells_per_value: int,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(stats_tally, "DENSE_CELLS_PER_VALUE", cells_per_value)
    # Rows past 255 (a uint8 key would fold them together when the values are sorted by row).
    rng = np.random.default_rng(3)
    pairs = [(slave, function) for slave in range(250) for function in (1, 2, 3, 4, 6, 16, 23, 43)]
    messages = [(*pairs[int(k)], [True, False, True], int(rng.integers(0, 10**9)), None, None)
                for k in rng.integers(0, len(pairs), 6000)]
    _tallied_as_plain(messages, [2000], [False])


def _tallied_as_plain(messages: list[tuple], sizes: list[int],  # type: ignore[type-arg]
                      drains_after: list[bool]) -> None:
    tally = FunctionTally(COUNTERS, BINS)
    drains: list[list[TalliedFunction]] = []
    position = turn = 0
    while position < len(messages):
        batch = messages[position : position + sizes[turn % len(sizes)]]
        rows = tally.rows(np.array([slave * KEY_SPAN + function for slave, function, *_ in batch], np.int64))
        tally.count(rows, [np.array([m[2][index] for m in batch], np.bool_) for index in range(COUNTERS)])
        for histogram, column in ((LATENCY, 3), (POLL_PERIOD, 4)):
            held = [k for k, m in enumerate(batch) if m[column] is not None]
            values = np.array([batch[k][column] for k in held], np.int64)
            tally.add(histogram, rows[held], np.array([_bin(v) for v in values.tolist()], np.intp), values)
        raised = [k for k, m in enumerate(batch) if m[5] is not None]
        tally.add_exceptions(rows[raised], np.array([batch[k][5] for k in raised], np.int64))
        if drains_after[turn % len(drains_after)]:
            drains.append(_taken(tally))
        position += len(batch)
        turn += 1
    drains.append(_taken(tally))
    summed, plain = _summed(drains), _plain(messages)
    assert set(summed) == set(plain)
    for pair, (counters, exceptions, values) in plain.items():
        got_counters, got_exceptions, got_histograms = summed[pair]
        assert got_counters == counters and got_exceptions == exceptions
        for got, held in zip(got_histograms, values, strict=True):
            expected = np.bincount([_bin(v) for v in held], minlength=BINS)
            assert got[0].tolist() == expected.tolist() and got[1] == len(held)
            assert (got[2], got[3]) == ((min(held), max(held)) if held else (None, None))
    assert tally.drain() == []  # nothing left once drained


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 400), min_size=1, max_size=20), st.lists(st.booleans(), min_size=1, max_size=8),
       st.integers(0, 2**32 - 1))
def test_statistics_read_midway_end_as_read_once(sizes: list[int], reads: list[bool], seed: int) -> None:
    # A bus of many pairs: the corpus's messages given other slaves and functions, so that the
    # tally grows its rows again and again (in copies: the corpus is cached).
    corpus = whole_capture()
    columns = {name: getattr(corpus, name).copy() for name in _COLUMNS}
    rng = np.random.default_rng(seed)
    named = (columns["slave"] >= 0) & (columns["function"] >= 0)
    columns["slave"][named] = rng.integers(0, 256, int(named.sum()))
    columns["function"][named] = rng.choice([1, 2, 3, 4, 5, 6, 15, 16, 23, 43], int(named.sum()))
    whole = MessageBatch(corpus.frames, *(columns[name] for name in _COLUMNS))
    reference = Statistics()
    reference.add_batch(whole)
    midway = Statistics()
    position = turn = 0
    while position < len(whole):
        midway.add_batch(_slice(whole, position, min(len(whole), position + sizes[turn % len(sizes)])))
        if reads[turn % len(reads)]:
            assert midway.per_function is midway.per_function
        position += sizes[turn % len(sizes)]
        turn += 1
    assert midway.to_dict() == reference.to_dict()


def test_a_full_tally_is_added_before_its_bins_could_overflow(monkeypatch: pytest.MonkeyPatch) -> None:
    """The statistics take the tally's rows out before it holds ``TALLY_HELD_MOST`` values
    (2**31 - 1: its bins are 32-bit); lowered here, so that it happens on the corpus."""
    whole = whole_capture()
    reference = Statistics()
    reference.add_batch(whole)
    monkeypatch.setattr(stats, "TALLY_HELD_MOST", 40)
    guarded = Statistics()
    for start in range(0, len(whole), 30):
        guarded.add_batch(_slice(whole, start, min(len(whole), start + 30)))
        assert guarded._tally.held < 40
    assert guarded._functions  # taken out along the way, not only when read
    assert guarded.to_dict() == reference.to_dict()
