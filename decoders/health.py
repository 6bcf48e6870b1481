"""The health of each slave, from a capture's statistics: what a report shows first.

A slave's row adds up its functions' counters (requests, answers, exceptions by code, CRC
errors, timeouts, retries, unexpected answers) and merges their latency and poll-period
histograms (percentiles to within 1 %, as ``stats``). Rows come worst first:

1. by error rate, (exceptions + CRC errors + timeouts) per request, highest first;
2. then by latency p95, longest first;
3. then by slave address.

Broadcasts (address 0) have no answers and no latency; their row counts only what was sent.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from decoders.stats import FunctionStats, Histogram, Statistics


@dataclass
class SlaveHealth:
    slave: int
    requests: int = 0
    responses: int = 0
    exceptions: Counter[int] = field(default_factory=Counter)
    crc_errors: int = 0
    timeouts: int = 0
    retries: int = 0
    unexpected: int = 0
    functions: list[int] = field(default_factory=list)
    latency: Histogram = field(default_factory=Histogram)
    poll_period: Histogram = field(default_factory=Histogram)

    @property
    def errors(self) -> int:
        return sum(self.exceptions.values()) + self.crc_errors + self.timeouts

    @property
    def error_rate(self) -> float | None:
        """Exceptions, CRC errors and timeouts per request; ``None`` without requests."""
        return self.errors / self.requests if self.requests else None

    def add(self, function: int, stats: FunctionStats) -> None:
        self.functions.append(function)
        self.requests += stats.requests + stats.broadcasts
        self.responses += stats.responses
        self.exceptions += stats.exceptions
        self.crc_errors += stats.crc_errors
        self.timeouts += stats.timeouts
        self.retries += stats.retries
        self.unexpected += stats.unexpected
        for mine, theirs in ((self.latency, stats.latency), (self.poll_period, stats.poll_period)):
            if theirs.count and theirs.minimum is not None and theirs.maximum is not None:
                mine.merge(theirs.counts, theirs.count, theirs.minimum, theirs.maximum)


def slave_health(statistics: Statistics) -> list[SlaveHealth]:
    """One row per slave, worst first (see the module docstring)."""
    rows: dict[int, SlaveHealth] = {}
    for (slave, function), stats in sorted(statistics.per_function.items()):
        rows.setdefault(slave, SlaveHealth(slave)).add(function, stats)
    return sorted(rows.values(), key=_worst_first)


def _worst_first(row: SlaveHealth) -> tuple[float, float, int]:
    p95 = row.latency.percentile(95)
    return (-(row.error_rate or 0.0), -(p95 or 0.0), row.slave)
