"""The report's charts as data: what ``report.js`` draws, from what the collector gathered.

Every time chart shares one axis: ``t0`` (the first bucket's start, ms since the epoch),
``width`` (ms per bucket) and a value per bucket per series (``null`` where a bucket has
none). Numbers carry 5 significant digits, which keeps an hour's report small.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.anomalies import KINDS
from decoders.health import slave_health
from decoders.stats import Histogram, bin_floor_ns
from sniffer.report.collect import ReportCollector

#: Bars of a latency distribution at most.
DISTRIBUTION_BARS = 60


def chart_data(collector: ReportCollector) -> dict[str, Any]:
    timeline = collector.timeline
    charts: list[dict[str, Any]] = []
    if timeline.used:
        charts.append(_chart("load", "Bus load", "%", "line",
                             [_series("bus load", timeline.values("wire_ns") / timeline.width_ns * 100)]))
        anomalies = [_series(KINDS[kind][0], timeline.values(f"anomaly:{kind}"))
                     for kind in KINDS if collector.anomalies.counts[kind]]
        if anomalies:
            charts.append(_chart("anomalies", "Anomalies per bucket", "frames", "bars", anomalies))
        charts += _latency_charts(collector)
        charts += _value_charts(collector)
    return {
        "t0": (timeline.origin_ns or 0) / 1e6,
        "width": timeline.width_ns / 1e6,
        "n": timeline.used,
        "charts": charts,
        "distribution": _distribution(collector),
    }


def _latency_charts(collector: ReportCollector) -> list[dict[str, Any]]:
    timeline, slaves = collector.timeline, sorted(collector.slaves)
    if not slaves:
        return []
    means, maxima = [], []
    for slave in slaves:
        count = timeline.values(f"latency:{slave}:count")
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(count > 0, timeline.values(f"latency:{slave}:sum") / count, np.nan)
        means.append(_series(f"slave {slave}", mean))
        maxima.append(_series(f"slave {slave}", timeline.values(f"latency:{slave}:max")))
    return [_chart("latency-mean", "Latency, mean per bucket", "ms", "line", means),
            _chart("latency-max", "Latency, longest per bucket", "ms", "line", maxima)]


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
    used = [np.flatnonzero(histogram.counts) for histogram in merged.values()]
    low, high = min(int(u[0]) for u in used), max(int(u[-1]) for u in used) + 1
    return [{"name": f"slave {slave}", **_bars(histogram, low, high)} for slave, histogram in sorted(merged.items())]


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
