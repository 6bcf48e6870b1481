"""The report's charts as data: what ``report.js`` draws, from what the collector gathered.

Every time chart shares one axis: ``t0`` (the first bucket's start, ms since the epoch),
``width`` (ms per bucket) and a value per bucket per series (``null`` where a bucket has
none). Numbers carry 5 significant digits, which keeps an hour's report small.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.anomalies import KINDS
from decoders.health import slave_health
from decoders.stats import Histogram, bin_floor_ns
from sniffer.report.collect import ReportCollector

#: Bars of a latency distribution at most.
DISTRIBUTION_BARS = 60
#: Slaves drawn each as their own line in the latency charts, the slowest (latency p95) first; the
#: others are one line, their longest per bucket or their distribution together: a chart of 30
#: slaves reads as one of 8.
SLAVES_DRAWN = 5


def chart_data(collector: ReportCollector) -> dict[str, Any]:
    timeline = collector.timeline
    charts: list[dict[str, Any]] = []
    if timeline.used:
        charts.append(_chart("load", "Bus load", "%", "line",
                             [_series("bus load", timeline.values("wire_ns") / timeline.width_ns * 100)]))
        # Retries apart: a timeout and its retry stacked in one bar would read as two troubles.
        anomalies = [_series(KINDS[kind][0], timeline.values(f"anomaly:{kind}"))
                     for kind in KINDS if collector.anomalies.counts[kind] and kind != "retry"]
        if anomalies:
            charts.append(_chart("anomalies", "Anomalies per bucket (retries below)", "frames", "bars", anomalies))
        if collector.anomalies.counts["retry"]:
            charts.append(_chart("retries", "Retries per bucket", "frames", "bars",
                                 [_series("retry", timeline.values("anomaly:retry"))]))
        charts += _latency_charts(collector)
        charts += _value_charts(collector)
    return {
        "t0": (timeline.origin_ns or 0) / 1e6,
        "width": timeline.width_ns / 1e6,
        "n": timeline.used,
        "charts": charts,
        "distribution": _distribution(collector),
    }


def _slowest(collector: ReportCollector) -> tuple[list[int], list[int]]:
    """The slaves drawn on their own (the slowest by latency p95, at most :data:`SLAVES_DRAWN`, in
    address order) and the others."""
    answered = {row.slave: row.latency.percentile(95) or 0.0 for row in slave_health(collector.statistics)
                if row.latency.count}
    slaves = sorted(collector.slaves | answered.keys())
    drawn = sorted(sorted(slaves, key=lambda slave: -answered.get(slave, 0.0))[:SLAVES_DRAWN])
    return drawn, [slave for slave in slaves if slave not in drawn]


def _latency_charts(collector: ReportCollector) -> list[dict[str, Any]]:
    """One chart: the longest latency per bucket of the slowest slaves, each a line, and of all the
    others as one line."""
    timeline = collector.timeline
    drawn, others = _slowest(collector)
    drawn = [slave for slave in drawn if slave in collector.slaves]
    others = [slave for slave in others if slave in collector.slaves]
    if not drawn:
        return []
    series = [_series(f"slave {slave}", timeline.values(f"latency:{slave}:max")) for slave in drawn]
    if others:
        stacked = np.vstack([timeline.values(f"latency:{slave}:max") for slave in others])
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a bucket none of them answered in: NaN
            longest = np.nanmax(stacked, axis=0)
        series.append(_series(f"{len(others)} other slaves" if len(others) > 1 else f"slave {others[0]}", longest))
    title = "Latency, longest per bucket" + (f" (the {len(drawn)} slowest slaves, the others as one)" if others else "")
    return [_chart("latency", title, "ms", "line", series)]


def _value_charts(collector: ReportCollector) -> list[dict[str, Any]]:
    """One chart per slave and unit: the series of that slave measured in that unit."""
    groups: dict[tuple[int, str], list[dict[str, Any]]] = {}
    timeline = collector.timeline
    for series in collector.values.series.values():
        key = series.key
        if f"{key}:last" not in timeline.series:
            continue
        entry = _series(f"{series.code} {series.kind}", timeline.values(f"{key}:last"))
        entry["band"] = [_numbers(timeline.values(f"{key}:min")), _numbers(timeline.values(f"{key}:max"))]
        entry["title"] = series.name
        groups.setdefault((series.slave, series.unit), []).append(entry)
    charts = []
    for index, ((slave, unit), entries) in enumerate(sorted(groups.items())):
        chart = _chart(f"values-{slave}-{index}", f"Slave {slave}: values", unit,  # the page adds " (unit)"
                       "line", entries)
        # A value holds until the next reading changes it: the line runs on across buckets without one.
        charts.append({**chart, "group": f"Slave {slave}", "hold": True})
    return charts


def _distribution(collector: ReportCollector) -> list[dict[str, Any]]:
    """Per slave, the latency distribution as bars on a logarithmic axis (ms, frames)."""
    # The slaves' latencies merged over their functions, as the health table has them.
    merged = {row.slave: row.latency for row in slave_health(collector.statistics) if row.latency.count}
    if not merged:
        return []
    _, others = _slowest(collector)
    rest, summed = Histogram(), 0
    for slave in others:
        if slave in merged:
            theirs = merged.pop(slave)
            assert theirs.minimum is not None and theirs.maximum is not None
            rest.merge(theirs.counts, theirs.count, theirs.minimum, theirs.maximum)
            summed += 1
    every = [*merged.values(), *([rest] if rest.count else [])]
    used = [np.flatnonzero(histogram.counts) for histogram in every]
    low, high = min(int(u[0]) for u in used), max(int(u[-1]) for u in used) + 1
    rows = [{"name": f"slave {slave}", **_bars(histogram, low, high)} for slave, histogram in sorted(merged.items())]
    if rest.count:
        bars = _bars(rest, low, high)
        if summed > 1:  # per slave, so that the line compares with the slaves drawn on their own
            bars["count"] = [round(count / summed, 1) for count in bars["count"] if count is not None]
        rows.append({"name": f"{summed} other slaves, per slave" if summed > 1 else f"slave {others[0]}", **bars})
    return rows


def _bars(histogram: Histogram, low: int, high: int) -> dict[str, list[float | None]]:
    """The histogram's bins from ``low`` to ``high`` in at most ``DISTRIBUTION_BARS`` bars (every
    slave gets the same bars, so that they line up)."""
    step = max(1, math.ceil((high - low) / DISTRIBUTION_BARS))
    counts = histogram.counts[low:high]
    counts = np.pad(counts, (0, -len(counts) % step)).reshape(-1, step).sum(axis=1)
    edges = low + np.arange(len(counts) + 1) * step
    bounds_ms = bin_floor_ns(edges) / 1e6
    return {"from": _numbers(bounds_ms[:-1]), "to": _numbers(bounds_ms[1:]), "count": counts.tolist()}


def _chart(chart_id: str, title: str, unit: str, kind: str, series: list[dict[str, Any]]) -> dict[str, Any]:
    return {"id": chart_id, "title": title, "unit": unit, "type": kind, "series": series}


def _series(name: str, values: npt.NDArray[np.float64]) -> dict[str, Any]:
    return {"name": name, "values": _numbers(values)}


def _numbers(values: npt.NDArray[np.float64]) -> list[float | None]:
    return [None if math.isnan(v) else float(f"{v:.5g}") for v in values.tolist()]
