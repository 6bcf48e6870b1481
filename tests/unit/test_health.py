"""The per-slave health rows: counters add up to the per-function statistics, worst first."""

from __future__ import annotations

from decoders.health import slave_health
from decoders.stats import Statistics
from tests.property.test_statistics_splits import whole_capture


def test_rows_add_up_and_come_worst_first() -> None:
    statistics = Statistics()
    statistics.add_batch(whole_capture())
    rows = slave_health(statistics)
    functions = statistics.per_function
    assert sorted(row.slave for row in rows) == sorted({slave for slave, _ in functions})
    for field in ("responses", "crc_errors", "timeouts", "retries", "unexpected"):
        assert sum(getattr(row, field) for row in rows) == sum(getattr(f, field) for f in functions.values())
    assert sum(row.requests for row in rows) == sum(f.requests + f.broadcasts for f in functions.values())
    assert sum(row.latency.count for row in rows) == sum(f.latency.count for f in functions.values())
    rates = [row.error_rate or 0.0 for row in rows]
    assert rates == sorted(rates, reverse=True) and rates[0] > 0
    for row in rows:
        stats = [functions[(row.slave, f)] for f in row.functions]
        assert row.latency.maximum == max((s.latency.maximum for s in stats if s.latency.maximum is not None),
                                          default=None)
