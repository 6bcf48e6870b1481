"""Traffic statistics per slave and function, in memory that does not grow with the capture.

Latency and poll-period percentiles come from histograms with logarithmic bins
(1 % wide, 1 µs to 1000 s), so a percentile is exact to within 1 %; minimum and
maximum are exact.
"""

from __future__ import annotations

import math
from collections import Counter, OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import Message, Role

_LOWEST_NS = 1_000.0
_RATIO = 1.01
_BINS = int(math.log(1e12 / _LOWEST_NS) / math.log(_RATIO)) + 2
_LOG_RATIO = math.log(_RATIO)
#: Request signatures remembered for poll periods (least recently seen forgotten first).
MAX_SIGNATURES = 4096
PERCENTILES = (50, 95, 99)


@dataclass
class Histogram:
    """Durations in nanoseconds: count, exact min/max, percentiles to within 1 %."""

    counts: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(_BINS, np.int64))
    count: int = 0
    minimum: int | None = None
    maximum: int | None = None

    def add(self, value_ns: int) -> None:
        self.count += 1
        self.minimum = value_ns if self.minimum is None else min(self.minimum, value_ns)
        self.maximum = value_ns if self.maximum is None else max(self.maximum, value_ns)
        self.counts[_bin(value_ns)] += 1

    def percentile(self, q: float) -> float | None:
        """The ``q``-th percentile in nanoseconds (bin centre, clamped to min/max)."""
        if not self.count or self.minimum is None or self.maximum is None:
            return None
        rank = max(1, math.ceil(q / 100 * self.count))
        index = int(np.searchsorted(np.cumsum(self.counts), rank))
        centre = 0.0 if index == 0 else _LOWEST_NS * _RATIO ** (index - 0.5)
        return float(min(max(centre, self.minimum), self.maximum))

    def summary(self) -> dict[str, float | int | None]:
        """min, percentiles and max in seconds, and the count."""
        seconds = {f"p{q}": _seconds(self.percentile(q)) for q in PERCENTILES}
        return {"count": self.count, "min": _seconds(self.minimum), **seconds, "max": _seconds(self.maximum)}


def _bin(value_ns: int) -> int:
    if value_ns < _LOWEST_NS:
        return 0
    return min(_BINS - 1, 1 + int(math.log(value_ns / _LOWEST_NS) / _LOG_RATIO))


def _seconds(value_ns: float | None) -> float | None:
    return None if value_ns is None else value_ns / 1e9


@dataclass
class FunctionStats:
    """What happened between the master(s) and one slave for one function code."""

    requests: int = 0
    responses: int = 0
    exceptions: Counter[int] = field(default_factory=Counter)
    broadcasts: int = 0
    crc_errors: int = 0
    timeouts: int = 0
    retries: int = 0
    unexpected: int = 0
    gap_1_5: int = 0
    short_idle: int = 0
    latency: Histogram = field(default_factory=Histogram)
    poll_period: Histogram = field(default_factory=Histogram)

    def to_dict(self) -> dict[str, Any]:
        return {
            "requests": self.requests,
            "responses": self.responses,
            "exceptions": {str(code): n for code, n in sorted(self.exceptions.items())},
            "broadcasts": self.broadcasts,
            "crc_errors": self.crc_errors,
            "timeouts": self.timeouts,
            "retries": self.retries,
            "unexpected": self.unexpected,
            "gap_1_5": self.gap_1_5,
            "short_idle": self.short_idle,
            "latency_s": self.latency.summary(),
            "poll_period_s": self.poll_period.summary(),
        }


@dataclass
class Statistics:
    """Accumulates messages; ``to_dict`` is the JSON form of ``stats`` and of the JSONL summary."""

    per_function: dict[tuple[int, int], FunctionStats] = field(default_factory=dict)
    roles: Counter[str] = field(default_factory=Counter)
    flags: Counter[str] = field(default_factory=Counter)
    frames: int = 0
    total_bytes: int = 0
    noise_bytes: int = 0
    crc_errors: int = 0
    wire_ns: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    _last_request_at: OrderedDict[bytes, int] = field(default_factory=OrderedDict)

    def add(self, message: Message) -> None:
        frame = message.frame
        self.frames += 1
        self.total_bytes += len(frame.data)
        self.wire_ns += frame.t_end_ns - frame.t_start_ns
        self.first_ns = frame.t_start_ns if self.first_ns is None else self.first_ns
        self.last_ns = frame.t_end_ns
        self.roles[message.role.value] += 1
        for name in message.flags.names:
            self.flags[name] += 1
        if message.role is Role.NOISE:
            self.noise_bytes += len(frame.data)
            return
        if not frame.crc_ok:
            self.crc_errors += 1
        if message.slave is None or message.function is None:
            return
        self._add_to(self._function(message.slave, message.function), message)

    def add_all(self, messages: list[Message]) -> None:
        for message in messages:
            self.add(message)

    def _function(self, slave: int, function: int) -> FunctionStats:
        key = (slave, function)
        stats = self.per_function.get(key)
        if stats is None:
            stats = self.per_function[key] = FunctionStats()
        return stats

    def _add_to(self, stats: FunctionStats, message: Message) -> None:
        flags, role = message.flags, message.role
        if role is Role.REQUEST:
            stats.requests += 1
            self._poll(stats, message)
        elif role is Role.RESPONSE:
            stats.responses += 1
        elif role is Role.EXCEPTION and message.exception_code is not None:
            stats.exceptions[message.exception_code] += 1
        elif role is Role.BROADCAST:
            stats.broadcasts += 1
        if message.latency_ns is not None and message.frame.crc_ok:
            stats.latency.add(message.latency_ns)
        stats.crc_errors += not message.frame.crc_ok
        stats.timeouts += bool(flags & FrameFlag.TIMEOUT)
        stats.retries += bool(flags & FrameFlag.RETRY)
        stats.unexpected += bool(flags & FrameFlag.UNEXPECTED)
        stats.gap_1_5 += bool(flags & FrameFlag.GAP_1_5)
        stats.short_idle += bool(flags & FrameFlag.SHORT_IDLE)

    def _poll(self, stats: FunctionStats, message: Message) -> None:
        """Interval since the same request (same bytes) was last sent: the poll period."""
        signature = message.frame.data
        now = message.frame.t_start_ns
        previous = self._last_request_at.pop(signature, None)
        if previous is not None:
            stats.poll_period.add(now - previous)
        self._last_request_at[signature] = now
        if len(self._last_request_at) > MAX_SIGNATURES:
            self._last_request_at.popitem(last=False)

    @property
    def duration_ns(self) -> int:
        return 0 if self.first_ns is None or self.last_ns is None else self.last_ns - self.first_ns

    @property
    def bus_load(self) -> float | None:
        """Share of the time the wire carried a frame."""
        return self.wire_ns / self.duration_ns if self.duration_ns > 0 else None

    def to_dict(self) -> dict[str, Any]:
        return {
            "frames": self.frames,
            "bytes": self.total_bytes,
            "duration_s": self.duration_ns / 1e9,
            "bus_load": self.bus_load,
            "roles": dict(sorted(self.roles.items())),
            "flags": dict(sorted(self.flags.items())),
            "crc_errors": self.crc_errors,
            "noise_bytes": self.noise_bytes,
            "per_slave_function": [
                {"slave": slave, "function": function, **stats.to_dict()}
                for (slave, function), stats in sorted(self.per_function.items())
            ],
        }
