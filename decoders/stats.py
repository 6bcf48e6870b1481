"""Traffic statistics per slave and function, in memory that does not grow with the capture.

Latency and poll-period percentiles come from histograms with logarithmic bins
(1 % wide, 1 µs to 1000 s), so a percentile is exact to within 1 %; minimum and
maximum are exact.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import UartError
from decoders.frame import FrameBatch, FrameFlag
from decoders.framing.rule_tables import padded_bytes
from decoders.hashing import FIBONACCI
from decoders.message import NONE, ROLE_CODE, ROLE_NAMES, ROLE_ORDER, MessageBatch, Role
from decoders.stats_tally import KEY_SPAN, LATENCY, POLL_PERIOD, FunctionTally

_LOWEST_NS = 1_000.0
_RATIO = 1.01
#: How many bins a latency histogram has (:func:`histogram_bins`).
HISTOGRAM_BINS = int(math.log(1e12 / _LOWEST_NS) / math.log(_RATIO)) + 2
_LOG_RATIO = math.log(_RATIO)
PERCENTILES = (50, 95, 99)
#: The tally's 32-bit bins are added to the statistics before they could hold this many values.
TALLY_HELD_MOST = 2**31 - 1


@dataclass
class Histogram:
    """Durations in nanoseconds: count, exact min/max, percentiles to within 1 %."""

    counts: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(HISTOGRAM_BINS, np.int64))
    count: int = 0
    minimum: int | None = None
    maximum: int | None = None

    def add(self, value_ns: int) -> None:
        self.add_many(np.array([value_ns], np.int64))

    def add_many(self, values_ns: npt.NDArray[np.int64]) -> None:
        if not len(values_ns):
            return
        self.count += len(values_ns)
        low, high = int(values_ns.min()), int(values_ns.max())
        self.minimum = low if self.minimum is None else min(self.minimum, low)
        self.maximum = high if self.maximum is None else max(self.maximum, high)
        self.counts += np.bincount(histogram_bins(values_ns), minlength=HISTOGRAM_BINS)

    def merge(self, counts: npt.NDArray[np.int64] | npt.NDArray[np.int32], count: int, low: int, high: int) -> None:
        """Add binned counts whose exact minimum and maximum are known."""
        self.counts += counts
        self.count += count
        self.minimum = low if self.minimum is None else min(self.minimum, low)
        self.maximum = high if self.maximum is None else max(self.maximum, high)

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


def bin_floor_ns(indices: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
    """The shortest duration each histogram bin holds: bin 0 everything under 1 µs, bin *i*
    from ``1 µs × 1.01**(i-1)``; a bin ends where the next begins."""
    floors: npt.NDArray[np.float64] = np.where(indices <= 0, 0.0, _LOWEST_NS * _RATIO ** (indices - 1.0))
    return floors


def histogram_bins(values_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """The histogram bin of each duration (see :func:`bin_floor_ns`; the last holds all above)."""
    scaled = np.maximum(values_ns, 1).astype(np.float64) / _LOWEST_NS
    bins = np.where(scaled < 1.0, 0, 1 + np.floor(np.log(np.maximum(scaled, 1.0)) / _LOG_RATIO))
    return np.minimum(bins, HISTOGRAM_BINS - 1).astype(np.intp)


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

    def merge(self, other: FunctionStats) -> None:
        """Add another capture's counts and histograms (exactly: the bins add up)."""
        for name in _COUNTS:
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.exceptions.update(other.exceptions)
        for mine, theirs in ((self.latency, other.latency), (self.poll_period, other.poll_period)):
            if theirs.minimum is not None and theirs.maximum is not None:
                mine.merge(theirs.counts, theirs.count, theirs.minimum, theirs.maximum)

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


_COUNTS = ("requests", "responses", "broadcasts", "crc_errors", "timeouts", "retries", "unexpected", "gap_1_5",
           "short_idle")


def _new_tally() -> FunctionTally:
    """An empty tally of the statistics' counters and histogram bins."""
    return FunctionTally(len(_COUNTS), HISTOGRAM_BINS)


#: :class:`LastSeen` has ``2**_SLOT_BITS`` slots.
_SLOT_BITS = 16


def _mixed(signatures: npt.NDArray[np.int64]) -> npt.NDArray[np.uint64]:
    """Each signature's Fibonacci hash: every bit of it weighs on its top bits. (A signature's low bits
    are its CRC: the 12 200 different requests of a polling batch had 9 300 different ones,
    fewer than random values would.)"""
    mixed: npt.NDArray[np.uint64] = signatures.view(np.uint64) * FIBONACCI
    return mixed


def _slots(signatures: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """Each signature's slot in :class:`LastSeen`: the top 16 bits of its hash."""
    return (_mixed(signatures) >> np.uint64(64 - _SLOT_BITS)).astype(np.intp)


class LastSeen:
    """When each request signature was last seen, in a fixed-size direct-mapped table.

    Memory stays fixed however many different requests a capture holds; a signature
    whose slot another one took since is simply not found (its next interval is lost).
    """

    SLOTS = 1 << _SLOT_BITS

    def __init__(self) -> None:
        self._signature = np.zeros(self.SLOTS, np.int64)
        self._time = np.full(self.SLOTS, NONE, np.int64)

    def lookup(self, signatures: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        slots = _slots(signatures)
        found: npt.NDArray[np.int64] = np.where(self._signature[slots] == signatures, self._time[slots], NONE)
        return found

    def store(self, signatures: npt.NDArray[np.int64], times: npt.NDArray[np.int64]) -> None:
        """When each of ``signatures`` (all different) was seen; of those that share a slot, the
        one seen last keeps it, whatever their order here."""
        slots = _slots(signatures)
        self._signature[slots] = signatures
        self._time[slots] = times
        lost = self._signature[slots] != signatures
        if lost.any():
            contested = np.zeros(self.SLOTS, np.bool_)
            contested[slots[lost]] = True
            rivals = np.flatnonzero(contested[slots])
            rivals = rivals[np.argsort(times[rivals])]
            self._signature[slots[rivals]] = signatures[rivals]
            self._time[slots[rivals]] = times[rivals]


#: The totals :meth:`Statistics.merge` adds up.
_TOTALS = ("frames", "total_bytes", "noise_bytes", "crc_errors", "uart_framing_errors", "uart_parity_errors",
           "skipped_reads", "skipped_bytes", "wire_ns")


class _NoLastSeen(LastSeen):
    """A :class:`LastSeen` without tables, for statistics that are only merged."""

    def __init__(self) -> None:
        self._signature = np.zeros(0, np.int64)
        self._time = np.zeros(0, np.int64)


_NO_LAST_SEEN = _NoLastSeen()


@dataclass(frozen=True)
class SkippedReads:
    """Reads a live capture did not decode (its decoding fell behind; the recording has them)."""

    reads: int
    size: int
    #: When the first read after them was taken.
    t_ns: int


@dataclass
class Statistics:
    """Accumulates message batches; ``to_dict`` is the JSON form of ``stats`` and of the JSONL summary."""

    #: Per slave and function (read through :attr:`per_function`, which adds what the tally holds).
    _functions: dict[tuple[int, int], FunctionStats] = field(default_factory=dict)
    #: What batches added per slave and function since :attr:`per_function` was last read.
    _tally: FunctionTally = field(default_factory=_new_tally, repr=False)
    roles: Counter[str] = field(default_factory=Counter)
    flags: Counter[str] = field(default_factory=Counter)
    frames: int = 0
    total_bytes: int = 0
    noise_bytes: int = 0
    crc_errors: int = 0
    #: Characters the receiver found wrong, by kind (a character may have both).
    uart_framing_errors: int = 0
    uart_parity_errors: int = 0
    #: Live capture: reads skipped because decoding fell behind, and their bytes (the recording has them).
    skipped_reads: int = 0
    skipped_bytes: int = 0
    wire_ns: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    _last_seen: LastSeen = field(default_factory=LastSeen)
    #: Merged statistics of many captures: the sum of their durations (see :meth:`merge`).
    spans_ns: int | None = None

    def add_batch(self, batch: MessageBatch) -> None:
        if not len(batch):
            return
        frames = batch.frames
        lengths = np.diff(frames.offsets)
        noise = batch.role == ROLE_CODE[Role.NOISE]
        self.frames += len(batch)
        self.total_bytes += int(lengths.sum())
        self.noise_bytes += int(lengths[noise].sum())
        self.crc_errors += int(np.count_nonzero(~frames.crc_ok & ~noise))
        if frames.uart_errors is not None:
            self.uart_framing_errors += int(np.count_nonzero(frames.uart_errors & UartError.FRAMING))
            self.uart_parity_errors += int(np.count_nonzero(frames.uart_errors & UartError.PARITY))
        self.wire_ns += int((frames.t_end_ns - frames.t_start_ns).sum())
        self.first_ns = int(frames.t_start_ns[0]) if self.first_ns is None else self.first_ns
        self.last_ns = int(frames.t_end_ns[-1])
        for code, count in enumerate(np.bincount(batch.role, minlength=len(ROLE_ORDER)).tolist()):
            if count:
                self.roles[ROLE_NAMES[code]] += count
        for flag in _FLAGS:
            count = int(np.count_nonzero(batch.flags & flag))
            if count:
                self.flags[_FLAG_NAMES[flag]] += count
        self._per_function(batch, ~noise & (batch.slave >= 0) & (batch.function >= 0))

    def _per_function(self, batch: MessageBatch, mask: npt.NDArray[np.bool_]) -> None:
        rows = np.flatnonzero(mask)
        tally = self._tally
        if tally.held + len(rows) >= TALLY_HELD_MOST:  # each message adds one value at most
            self._add_tallied()
        pairs = tally.rows(batch.slave[rows].astype(np.int64) * KEY_SPAN + batch.function[rows])
        role, flags = batch.role[rows], batch.flags[rows]
        crc_ok = batch.frames.crc_ok[rows]
        counted = {
            "requests": role == ROLE_CODE[Role.REQUEST],
            "responses": role == ROLE_CODE[Role.RESPONSE],
            "broadcasts": role == ROLE_CODE[Role.BROADCAST],
            "crc_errors": ~crc_ok,
            **{name: (flags & flag) != 0 for name, flag in _FLAG_FIELDS.items()},
        }
        tally.count(pairs, [counted[name] for name in _COUNTS])
        exception = role == ROLE_CODE[Role.EXCEPTION]
        if exception.any():
            tally.add_exceptions(pairs[exception], batch.exception_code[rows][exception])
        latency = batch.latency_ns[rows]
        answered = (latency >= 0) & crc_ok
        latency = latency[answered]
        tally.add(LATENCY, pairs[answered], histogram_bins(latency), latency)
        asked = counted["requests"]
        self._poll_periods(batch, rows[asked], pairs[asked])

    @property
    def per_function(self) -> dict[tuple[int, int], FunctionStats]:
        """The figures per slave and function (read at the end, or by a live view each second:
        what the batches gathered in the tally is added to them here)."""
        self._add_tallied()
        return self._functions

    def _add_tallied(self) -> None:
        for tallied in self._tally.drain():
            stats = self._function(tallied.slave, tallied.function)
            for name, grown in zip(_COUNTS, tallied.counters, strict=True):
                if grown:
                    setattr(stats, name, getattr(stats, name) + grown)
            stats.exceptions.update(tallied.exceptions)
            for histogram, gathered in zip((stats.latency, stats.poll_period), tallied.histograms, strict=True):
                if gathered is not None:
                    histogram.merge(gathered.counts, gathered.count, gathered.low, gathered.high)
        self._tally.clear()

    def _poll_periods(
        self, batch: MessageBatch, rows: npt.NDArray[np.intp], pairs: npt.NDArray[np.int64]
    ) -> None:
        """Interval since the same request (same bytes) was last sent: the poll period
        (``pairs``: each request's row in the tally)."""
        if not len(rows):
            return
        frames = batch.frames
        signatures = request_signatures(frames, rows)
        times = frames.t_start_ns[rows]
        order = _by_signature_then_time(signatures, times)
        signatures, times, pairs = signatures[order], times[order], pairs[order]
        first_of_run = np.ones(len(order), np.bool_)
        first_of_run[1:] = signatures[1:] != signatures[:-1]
        previous = np.empty(len(order), np.int64)
        previous[1:] = times[:-1]
        previous[first_of_run] = self._last_seen.lookup(signatures[first_of_run])
        last_of_run = np.append(first_of_run[1:], True)
        self._last_seen.store(signatures[last_of_run], times[last_of_run])
        known = previous != NONE
        periods = (times - previous)[known]
        self._tally.add(POLL_PERIOD, pairs[known], histogram_bins(periods), periods)

    def _function(self, slave: int, function: int) -> FunctionStats:
        key = (slave, function)
        stats = self._functions.get(key)
        if stats is None:
            stats = self._functions[key] = FunctionStats()
        return stats

    @property
    def duration_ns(self) -> int:
        if self.spans_ns is not None:
            return self.spans_ns
        return 0 if self.first_ns is None or self.last_ns is None else self.last_ns - self.first_ns

    def merge(self, other: Statistics) -> None:
        """Add the statistics of another capture (many captures at once, as ``stats --each``):
        counters and histograms add up exactly; the duration is the captures' durations summed,
        so that the bus load is the share of their time a wire was busy."""
        spans = self.duration_ns + other.duration_ns
        self._add_tallied()
        for key, theirs in sorted(other.per_function.items()):
            self._function(*key).merge(theirs)
        self.roles.update(other.roles)
        self.flags.update(other.flags)
        for name in _TOTALS:
            setattr(self, name, getattr(self, name) + getattr(other, name))
        firsts = [t for t in (self.first_ns, other.first_ns) if t is not None]
        lasts = [t for t in (self.last_ns, other.last_ns) if t is not None]
        self.first_ns, self.last_ns = min(firsts, default=None), max(lasts, default=None)
        self.spans_ns = spans

    def portable(self) -> Statistics:
        """These statistics without the per-capture state of poll periods (1 MB): what another
        process sends back to be merged."""
        return replace(self, _functions=self.per_function, _last_seen=_NO_LAST_SEEN, _tally=_new_tally())

    @property
    def bus_load(self) -> float | None:
        """Share of the time the wire carried a frame."""
        return self.wire_ns / self.duration_ns if self.duration_ns > 0 else None

    def to_dict(self) -> dict[str, Any]:
        skipped = {"skipped_reads": self.skipped_reads, "skipped_bytes": self.skipped_bytes} \
            if self.skipped_reads else {}
        return {
            "frames": self.frames,
            "bytes": self.total_bytes,
            "duration_s": self.duration_ns / 1e9,
            "bus_load": self.bus_load,
            "roles": dict(sorted(self.roles.items())),
            "flags": dict(sorted(self.flags.items())),
            "crc_errors": self.crc_errors,
            "noise_bytes": self.noise_bytes,
            "uart_errors": {"framing": self.uart_framing_errors, "parity": self.uart_parity_errors},
            **skipped,
            "per_slave_function": [
                {"slave": slave, "function": function, **stats.to_dict()}
                for (slave, function), stats in sorted(self.per_function.items())
            ],
        }


_FLAGS = [int(f) for f in FrameFlag if f]
_FLAG_NAMES = {int(f): f.names[0] for f in FrameFlag if f}
_FLAG_FIELDS = {
    "timeouts": int(FrameFlag.TIMEOUT), "retries": int(FrameFlag.RETRY), "unexpected": int(FrameFlag.UNEXPECTED),
    "gap_1_5": int(FrameFlag.GAP_1_5), "short_idle": int(FrameFlag.SHORT_IDLE),
}  # fmt: skip


def _by_signature_then_time(signatures: npt.NDArray[np.int64], times: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """An order that puts equal signatures together, each run in time order, as
    ``np.lexsort((times, signatures))`` does (runs in another order). When the times are in
    order already, a run in time order is a run in index order, which two stable radix sorts
    (numpy sorts 16-bit keys stably by radix) by 32 bits of each signature's hash keep; unless
    two signatures share a hash: a third to a half of ``lexsort``'s time on a batch's requests."""
    if bool((times[1:] < times[:-1]).any()):
        return np.lexsort((times, signatures))
    mixed = _mixed(signatures) >> np.uint64(32)
    order = np.argsort(mixed.astype(np.uint16), kind="stable")
    order = order[np.argsort((mixed[order] >> np.uint64(16)).astype(np.uint16), kind="stable")]
    grouped, hashes = signatures[order], mixed[order]
    if ((grouped[1:] != grouped[:-1]) & (hashes[1:] == hashes[:-1])).any():
        return np.lexsort((times, signatures))
    return order


def request_signatures(frames: FrameBatch, rows: npt.NDArray[np.intp]) -> npt.NDArray[np.int64]:
    """A 64-bit signature per request: address, function, the next four bytes, length and CRC.

    Two different requests share one only if they agree in all of these, CRC included
    (1 in 65 536 for requests longer than 8 bytes that differ only after byte 6).
    """
    starts, ends = frames.offsets[rows], frames.offsets[rows + 1]
    padded = padded_bytes(frames.data)
    head = np.zeros(len(rows), np.int64)
    for k in range(6):
        head = (head << 8) | padded[k:].take(starts)  # byte k, no index array made
    tail = padded.take(ends - 2).astype(np.int64) << 8 | padded.take(ends - 1)
    return (head << 16 | tail) ^ ((ends - starts) << 56)
