"""Two captures' statistics side by side: what changed per slave and function.

"Did the termination fix help?" is a question about rates and latencies of the same exchanges
before and after. For every slave and function in either capture this gives both sides'
measures (requests, error and timeout rates, latency percentiles, poll period) and a verdict:

* ``worse`` when the error rate rose by more than ``RATE_STEP`` (half a percentage point), or the
  latency p95 by more than ``LATENCY_STEP`` (20 %) and at least ``LATENCY_FLOOR_NS`` (0.5 ms);
* ``better`` for the same falls (and none of the rises);
* ``new`` / ``gone`` when only one capture has the pair; ``same`` otherwise.

The error rate counts exceptions, CRC errors and timeouts per request.
"""

from __future__ import annotations

from dataclasses import dataclass

from decoders.stats import FunctionStats, Statistics

RATE_STEP = 0.005
LATENCY_STEP = 0.20
LATENCY_FLOOR_NS = 500_000


@dataclass(frozen=True)
class Measures:
    """One slave and function in one capture."""

    requests: int
    responses: int
    exceptions: int
    crc_errors: int
    timeouts: int
    retries: int
    latency_p50_ns: float | None
    latency_p95_ns: float | None
    latency_max_ns: float | None
    poll_p50_ns: float | None

    @property
    def error_rate(self) -> float | None:
        """Exceptions, CRC errors and timeouts per request; ``None`` without requests."""
        if not self.requests:
            return None
        return (self.exceptions + self.crc_errors + self.timeouts) / self.requests

    @property
    def timeout_rate(self) -> float | None:
        return self.timeouts / self.requests if self.requests else None

    @classmethod
    def of(cls, stats: FunctionStats) -> Measures:
        latency = stats.latency
        return cls(stats.requests, stats.responses, sum(stats.exceptions.values()), stats.crc_errors, stats.timeouts,
                   stats.retries, latency.percentile(50), latency.percentile(95),
                   None if latency.maximum is None else float(latency.maximum), stats.poll_period.percentile(50))


@dataclass(frozen=True)
class Change:
    """One slave and function, before and after (``None``: not in that capture)."""

    slave: int
    function: int
    before: Measures | None
    after: Measures | None

    @property
    def verdict(self) -> str:
        before, after = self.before, self.after
        if before is None:
            return "new"
        if after is None:
            return "gone"
        rises, falls = _moves(before, after)
        if rises:
            return "worse"
        return "better" if falls else "same"


def _moves(before: Measures, after: Measures) -> tuple[bool, bool]:
    """Whether the error rate or the latency p95 rose, and whether one fell, by more than the steps."""
    rises = falls = False
    if before.error_rate is not None and after.error_rate is not None:
        rises |= after.error_rate - before.error_rate > RATE_STEP
        falls |= before.error_rate - after.error_rate > RATE_STEP
    low, high = before.latency_p95_ns, after.latency_p95_ns
    if low is not None and high is not None:
        step = max(LATENCY_STEP * low, LATENCY_FLOOR_NS)
        rises |= high - low > step
        falls |= low - high > step
    return rises, falls


def compare(before: Statistics, after: Statistics) -> list[Change]:
    """Every slave and function of either capture, in order of slave and function."""
    pairs = sorted(set(before.per_function) | set(after.per_function))
    return [Change(slave, function, _measures(before, (slave, function)), _measures(after, (slave, function)))
            for slave, function in pairs]


def _measures(statistics: Statistics, pair: tuple[int, int]) -> Measures | None:
    stats = statistics.per_function.get(pair)
    return None if stats is None else Measures.of(stats)
