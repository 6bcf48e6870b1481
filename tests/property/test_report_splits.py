"""Hypothesis: what the report gathers does not depend on how the capture is cut into batches,
and its timeline equals a direct count at the width it ends with; timelines of separate
captures merged equal one timeline given every time.

The anomalies keep the frames around them from the neighbouring batches; the timeline's buckets
merge in pairs as times run past its end. Both are checked against one batch holding the whole
capture (the 'everything' corpus: every fault the corpus knows), and the timeline against numpy
doing the sums, maxima, minima and last values of each final bucket directly.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.decoded_batch import AnnotatedBatch
from decoders.message import UNDECODED, MessageBatch
from decoders.timeline import Timeline
from sniffer.report.collect import Provenance, ReportCollector
from tests.property.test_statistics_splits import _slice, whole_capture


def _gathered(batches: list[MessageBatch]) -> ReportCollector:
    collector = ReportCollector(Provenance(files=[], command="", tool_version="", profiles=[]))
    for batch in batches:
        collector.messages(AnnotatedBatch(batch, [UNDECODED] * len(batch)))
    return collector


def _cut(whole: MessageBatch, sizes: list[int]) -> list[MessageBatch]:
    batches, position, turn = [], 0, 0
    while position < len(whole):
        size = sizes[turn % len(sizes)]
        batches.append(_slice(whole, position, min(len(whole), position + size)))
        position += size
        turn += 1
    return batches


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 300), min_size=1, max_size=30))
def test_report_over_random_batch_splits(sizes: list[int]) -> None:
    whole = whole_capture()
    reference, split = _gathered([whole]), _gathered(_cut(whole, sizes))
    assert split.anomalies.counts == reference.anomalies.counts
    assert sum(reference.anomalies.counts.values()) > 50
    for kind, kept in reference.anomalies.kept.items():
        assert split.anomalies.kept[kind] == kept, kind
        for anomaly in kept:
            if anomaly.with_context:  # two frames either side, but at the capture's ends
                assert len(anomaly.before) == min(2, anomaly.row.index - whole.frames.first_index)
    assert split.timeline.width_ns == reference.timeline.width_ns
    assert split.timeline.used == reference.timeline.used
    assert split.timeline.series.keys() == reference.timeline.series.keys()
    for name in reference.timeline.series:
        np.testing.assert_allclose(split.timeline.values(name), reference.timeline.values(name), rtol=1e-9,
                                   equal_nan=True, err_msg=name)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 10**12), st.floats(-1e6, 1e6, allow_nan=False)), min_size=1,
                max_size=200),
       st.integers(1, 20))
def test_timeline_equals_a_direct_count(points: list[tuple[int, float]], pieces: int) -> None:
    points.sort()
    times = np.array([t for t, _ in points], np.int64) + 1_700_000_000 * 10**9
    values = np.array([v for _, v in points])
    timeline = Timeline(buckets=16, width_ns=1000)
    for chunk in np.array_split(np.arange(len(points)), pieces):
        for merge in ("sum", "max", "min", "last"):
            timeline.add(merge, merge, times[chunk], values[chunk])  # type: ignore[arg-type]
    width = timeline.width_ns
    origin = times[0] - times[0] % width
    assert timeline.origin_ns == origin
    # The narrowest width (a power of two times the first) whose buckets from an aligned origin hold every time.
    assert times[-1] - origin < 16 * width
    assert width == 1000 or times[-1] - (times[0] - times[0] % (width // 2)) >= 16 * (width // 2)
    where = (times - origin) // width
    assert timeline.used == where[-1] + 1
    sums = np.zeros(timeline.used)
    np.add.at(sums, where, values)
    np.testing.assert_allclose(timeline.values("sum"), sums, rtol=1e-9, atol=1e-6)
    for bucket in range(timeline.used):
        mine = values[where == bucket]
        expected = (np.max(mine), np.min(mine), mine[-1]) if len(mine) else (np.nan,) * 3
        found = tuple(timeline.values(name)[bucket] for name in ("max", "min", "last"))
        np.testing.assert_equal(found, expected)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 10**9), st.integers(1, 10**8)), min_size=1, max_size=100),
       st.integers(1, 10))
def test_spans_fill_each_bucket_with_what_it_covers(spans: list[tuple[int, int]], pieces: int) -> None:
    """Wire time spread over buckets: the total is kept, and no bucket holds more than a width of
    the union of the spans (frames on one wire do not overlap; here they may, so per span)."""
    spans.sort()
    starts = np.array([s for s, _ in spans], np.int64)
    ends = starts + np.array([d for _, d in spans], np.int64)
    timeline = Timeline(buckets=8, width_ns=10_000)
    for chunk in np.array_split(np.arange(len(spans)), pieces):
        timeline.add_spans("wire", starts[chunk], ends[chunk])
    total = timeline.values("wire")
    assert np.isclose(total.sum(), float((ends - starts).sum()))
    assert np.all(total <= timeline.width_ns * len(spans) + 1e-6)
    single = Timeline(buckets=8, width_ns=10_000)
    for start, end in zip(starts.tolist(), ends.tolist(), strict=True):
        single.add_spans("one", np.array([start]), np.array([end]))
        assert np.all(single.values("one") <= single.width_ns + 1e-6)
        single = Timeline(buckets=8, width_ns=10_000)


def _timeline_of(times: np.ndarray, values: np.ndarray, names: tuple[str, ...]) -> Timeline:
    timeline = Timeline(buckets=16, width_ns=1000)
    for merge in names:
        timeline.add(merge, merge, times, values)  # type: ignore[arg-type]
    return timeline


def _assert_same(merged: Timeline, whole: Timeline) -> None:
    assert (merged.origin_ns, merged.width_ns, merged.used) == (whole.origin_ns, whole.width_ns, whole.used)
    assert merged.series.keys() == whole.series.keys()
    for name in whole.series:
        np.testing.assert_allclose(merged.series[name].values, whole.series[name].values, rtol=1e-9, atol=1e-6,
                                   equal_nan=True, err_msg=name)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 10**7), st.floats(-1e6, 1e6, allow_nan=False)), min_size=1,
                max_size=120),
       st.lists(st.integers(0, 120), max_size=6), st.integers(0, 10**12))
def test_timelines_of_captures_in_time_order_merge_into_one(points: list[tuple[int, float]], cuts: list[int],
                                                             start: int) -> None:
    """Captures one after the other (``report --each``): each its own timeline, merged in order."""
    points.sort()
    times = np.array([t for t, _ in points], np.int64) + start
    values = np.array([v for _, v in points])
    names = ("sum", "max", "min", "last")
    merged = Timeline(buckets=16, width_ns=1000)
    for part in np.split(np.arange(len(points)), sorted({min(cut, len(points)) for cut in cuts})):
        merged.merge(_timeline_of(times[part], values[part], names))
    _assert_same(merged, _timeline_of(times, values, names))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(st.tuples(st.integers(0, 10**8), st.floats(-1e6, 1e6, allow_nan=False)), min_size=1,
                         max_size=40), min_size=1, max_size=5))
def test_timelines_merge_in_any_order(captures: list[list[tuple[int, float]]]) -> None:
    """Captures that overlap or come out of order: sums, maxima and minima are still exact."""
    names = ("sum", "max", "min")
    merged = Timeline(buckets=16, width_ns=1000)
    for points in captures:
        points.sort()
        merged.merge(_timeline_of(np.array([t for t, _ in points], np.int64), np.array([v for _, v in points]),
                                  names))
    every = sorted(point for points in captures for point in points)
    _assert_same(merged, _timeline_of(np.array([t for t, _ in every], np.int64), np.array([v for _, v in every]),
                                      names))
