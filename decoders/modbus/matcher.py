"""Roles and pairing on one wire: which frame asks, which answers, and what went unanswered.

A passive tap sees requests and responses interleaved on one line. The matcher
decides each frame's role from its shape (the length rules), its position and the
requests still open, pairs every response and exception with its request, and flags
``timeout``, ``retry`` and ``unexpected``.

* Requests are open per slave address, so two masters polling different slaves
  interleave without disturbing each other.
* A frame that has the shape of both a request and a response (FC 5/6/8/22 echoes
  are byte-identical) is the response when it answers the open request to its
  slave, else a request: order decides, not guessing.
* A response answers an open request when slave and function agree and its
  content fits the request (byte count for the registers asked, echoed address,
  sub-function or MEI type).
* A request is ``timeout`` when another request to the same slave comes first, or
  when the response timeout passes (fixed, or derived from the traffic: ten times
  the longest recent latency, at least 100 ms, at most 1 s; on host captures never
  less than the delivery delay the framer learned from the reads, up to 3 s).
* A request is ``retry`` when it repeats, byte for byte, the previous request to
  that slave that got no valid answer.
* Address 0 is a broadcast: nobody answers it, and a frame that looks like an
  answer to it is ``unexpected``. An FC 5/6 broadcast and its echo are the same bytes:
  the repeat is the echo only within the least response timeout (the fixed one, else
  100 ms) of the broadcast's end; later it is the master broadcasting again, as masters
  repeat a write to all drives after their turnaround delay.
* An answer before the capture's first request is not ``unexpected``: the recording
  began between a request and its answer (every rotated file of a long recording
  read alone, ``--each``, begins so about half the time).

A request is held back until its outcome is known, and frames behind it with it,
so that messages leave in capture order with their flags final.

Speed: on a healthy bus no request is open between exchanges. From such a state,
a run of consecutive request/answer pairs (same slave and function, fitting
content, valid answer CRC, answered sooner than the response timeout can be) has one
possible outcome, which numpy assigns in bulk: only a slave whose last request
failed needs a look, at its first request of the run (a retry, or not); the runs' roles,
requests and latencies are written once the batch's loop is done. The loop handles the
frames outside such runs one by one, reading them from short windows of lists
(:func:`~decoders.modbus.pair_runs.frame_lists`).
"""

from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from decoders.frame import USS, FrameBatch, FrameFlag, concat_frames, slice_frames
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from decoders.modbus.codes import BROADCAST_ADDRESS, EXCEPTION_BIT
from decoders.modbus.layouts import MEI_EXCEPTION_LENGTH
from decoders.modbus.pair_runs import WINDOW, SettledRuns, frame_lists, pair_runs
from decoders.modbus.shapes import FITS_REQUEST, FITS_RESPONSE, MIN_ADU, Shapes, frame_shapes
from decoders.uss_pairing import UssPairing

MIN_TIMEOUT_NS = 100_000_000
MAX_TIMEOUT_NS = 1_000_000_000
TIMEOUT_PER_LATENCY = 10
LATENCY_WINDOW = 256
LEARN_EVERY = 32
ADDRESSES = 256

REQUEST = ROLE_CODE[Role.REQUEST]
RESPONSE = ROLE_CODE[Role.RESPONSE]
EXCEPTION = ROLE_CODE[Role.EXCEPTION]
BROADCAST = ROLE_CODE[Role.BROADCAST]
NOISE = ROLE_CODE[Role.NOISE]
UNKNOWN = ROLE_CODE[Role.UNKNOWN]
TIMEOUT = int(FrameFlag.TIMEOUT)
RETRY = int(FrameFlag.RETRY)
UNEXPECTED = int(FrameFlag.UNEXPECTED)
_COLUMNS = {
    "role": np.uint8, "slave": np.int16, "function": np.int16, "exception_code": np.int16,
    "flags": np.uint16, "request_index": np.int64, "latency_ns": np.int64,
}  # fmt: skip


@dataclass
class _OpenRequests:
    """The request awaiting its answer, per slave address, in lists indexed by address
    (the matcher's inner loop reads them for every frame)."""

    position: list[int] = field(default_factory=lambda: [NONE] * ADDRESSES)
    index: list[int] = field(default_factory=lambda: [NONE] * ADDRESSES)
    function: list[int] = field(default_factory=lambda: [NONE] * ADDRESSES)
    key: list[int] = field(default_factory=lambda: [NONE] * ADDRESSES)
    t_end_ns: list[int] = field(default_factory=lambda: [NONE] * ADDRESSES)
    data: list[bytes] = field(default_factory=lambda: [b""] * ADDRESSES)
    slaves: set[int] = field(default_factory=set)

    def close(self, slave: int) -> None:
        self.position[slave] = NONE
        self.slaves.discard(slave)


@dataclass
class _Held:
    """Messages classified but not yet released, as int64 columns over ``frames``."""

    frames: FrameBatch | None = None
    columns: dict[str, npt.NDArray[np.int64]] = field(
        default_factory=lambda: {name: np.zeros(0, np.int64) for name in _COLUMNS}
    )

    def __len__(self) -> int:
        return len(self.columns["role"])

    def extend(self, frames: FrameBatch, new: dict[str, npt.NDArray[np.int64]]) -> None:
        self.frames = frames if self.frames is None else concat_frames([self.frames, frames])
        self.columns = {name: np.concatenate([self.columns[name], new[name]]) for name in _COLUMNS}

    def take(self, count: int) -> MessageBatch:
        """The first ``count`` messages, removed from the held ones."""
        assert self.frames is not None
        frames = slice_frames(self.frames, 0, count)
        self.frames = slice_frames(self.frames, count, len(self.frames))
        taken = {name: self.columns[name][:count].astype(dtype) for name, dtype in _COLUMNS.items()}
        self.columns = {name: values[count:] for name, values in self.columns.items()}
        taken["flags"] |= frames.flags
        return MessageBatch(frames, **taken)


@dataclass
class Matcher:
    """Feeds frame batches in capture order; returns message batches whose flags are final."""

    response_timeout_ns: int | None = None
    _held: _Held = field(default_factory=_Held)
    _open: _OpenRequests = field(default_factory=_OpenRequests)
    _failed: dict[int, bytes] = field(default_factory=dict)
    #: The last broadcast's function, request key and end.
    _last_broadcast: tuple[int, int, int] | None = None
    _latencies: deque[int] = field(default_factory=lambda: deque(maxlen=LATENCY_WINDOW))
    _learned: int = 0
    _adaptive_timeout_ns: int = MAX_TIMEOUT_NS
    #: Settle clean request/answer runs in bulk; ``False`` is the plain frame-by-frame path,
    #: the reference the tests hold the shortcut to.
    bulk: bool = True
    _uss: UssPairing = field(default_factory=UssPairing)
    #: The least a derived timeout may be: on host captures, how late the capture's read
    #: loop delivers bytes (an answer often comes one read, a read timeout, after its request).
    delivery_floor_ns: int = 0
    #: Whether a request has been seen: answers before the first one are not ``unexpected``.
    _asked: bool = False

    @property
    def _least_timeout_ns(self) -> int:
        """The least the response timeout may be while this batch is matched: a fixed one (which
        may be shorter than a derived one ever is), else the least a derived one is."""
        return self.response_timeout_ns if self.response_timeout_ns is not None else MIN_TIMEOUT_NS

    @property
    def timeout_ns(self) -> int:
        """The response timeout in force."""
        if self.response_timeout_ns is not None:
            return self.response_timeout_ns
        return max(self._adaptive_timeout_ns, self.delivery_floor_ns)

    def feed(self, frames: FrameBatch) -> MessageBatch:
        held = self._held
        first = len(held)
        shapes = frame_shapes(frames)
        held.extend(frames, _defaults(frames, shapes))
        self._classify(frames, shapes, first)
        return self._release()

    def tick(self, now_ns: int) -> MessageBatch:
        """Live capture: requests whose response timeout has passed by ``now_ns`` are
        timeouts, and the messages they held back are released."""
        if self._open.slaves and now_ns > self._deadline():
            self._expire(now_ns)
        if self._held.frames is None:
            return _empty_batch()
        return self._release()

    def _release(self) -> MessageBatch:
        """The held messages before the earliest open request."""
        positions = self._open.position
        earliest = min((positions[s] for s in self._open.slaves), default=len(self._held))
        for slave in self._open.slaves:
            positions[slave] -= earliest
        return self._held.take(earliest)

    def flush(self) -> MessageBatch:
        """At the end of the capture: requests still open stay without a verdict."""
        self._open = _OpenRequests()
        if self._held.frames is None:
            return _empty_batch()
        return self._held.take(len(self._held))

    def _classify(self, frames: FrameBatch, shapes: Shapes, first: int) -> None:
        lengths = np.diff(frames.offsets)
        uss = frames.protocols() == USS
        active = np.flatnonzero(~frames.is_noise & (lengths >= MIN_ADU) & ~uss)
        runs = pair_runs(frames, shapes, active, within_ns=self._least_timeout_ns)
        settled = SettledRuns(frames, active) if self.bulk and runs.any() else None
        self._visit(frames, shapes, active, (runs, settled), first)
        if settled is not None:
            settled.write(self._held.columns, first)
        if uss.any():
            self._uss.assign(frames, np.flatnonzero(uss), self._held.columns, first)
        if len(frames):
            last_start = int(frames.t_start_ns[-1])
            if last_start > self._deadline():
                self._expire(last_start)

    def _visit(  # noqa: PLR0915
        self, frames: FrameBatch, shapes: Shapes, active: npt.NDArray[np.intp],
        bulk: tuple[npt.NDArray[np.int64], SettledRuns | None], first: int
    ) -> None:
        """The frames of ``active`` in order; from a clean state, ``runs[k]`` pairs starting
        at active frame k are settled in bulk, into ``settled`` (``None``: none are)."""
        runs, settled = bulk
        columns = self._held.columns
        role, flags = columns["role"], columns["flags"]
        requests, failed = self._open, self._failed
        open_position, open_function, open_key = requests.position, requests.function, requests.key
        open_end, open_index, open_data, open_slaves = requests.t_end_ns, requests.index, requests.data, requests.slaves
        data, first_index = frames.data, frames.first_index
        # Read one by one, not as lists: the loop visits few of them, runs settle the rest.
        at_active, run_at = active.item, runs.item
        # The frames the loop visits, as lists of a window of the batch (see frame_lists).
        base = window_end = 0
        deadline = self._deadline()
        timeout = self.timeout_ns
        k, count = 0, len(active)
        while k < count:
            pairs = run_at(k)
            if pairs and settled is not None and not open_slaves:
                self._settle_pairs(settled, k, pairs, first)
                k += 2 * pairs
                timeout = self.timeout_ns
                continue
            i = at_active(k)
            k += 1
            if i >= window_end:
                base, window_end = i, min(i + WINDOW, len(frames))
                offsets, slaves, functions, shape_of, request_keys, response_keys, crc_oks, t_starts, t_ends = \
                    frame_lists(frames, shapes, base, window_end)
            j = i - base
            t_start = t_starts[j]
            if t_start > deadline:
                self._expire(t_start)
                deadline = self._deadline()
            slave, raw, shape, position = slaves[j], functions[j], shape_of[j], first + i
            if raw & EXCEPTION_BIT:
                code = data[offsets[j] + (3 if offsets[j + 1] - offsets[j] == MEI_EXCEPTION_LENGTH else 2)]
                self._exception(position, slave, raw & ~EXCEPTION_BIT, shape, code=code, crc_ok=crc_oks[j],
                                t_start=t_start)
                deadline, timeout = self._deadline(), self.timeout_ns
                continue
            if slave == BROADCAST_ADDRESS:
                self._broadcast(position, raw, shape, (request_keys[j], response_keys[j]), (t_start, t_ends[j]))
                continue
            pending = open_position[slave]
            if (
                shape & FITS_RESPONSE
                and pending != NONE
                and open_function[slave] == raw
                and open_key[slave] == response_keys[j]
            ):
                role[position] = RESPONSE
                self._answer(position, slave, crc_oks[j], t_start)
                timeout = self.timeout_ns
                # The deadline stays as it is: at worst too early, which costs one needless check.
            elif shape & FITS_REQUEST:
                adu = data[offsets[j] : offsets[j + 1]]
                if pending != NONE:
                    self._fail(slave)
                role[position] = REQUEST
                self._asked = True
                if failed and failed.get(slave) == adu:
                    flags[position] = RETRY
                open_position[slave], open_index[slave] = position, first_index + i
                open_function[slave], open_key[slave] = raw, request_keys[j]
                open_end[slave], open_data[slave] = t_ends[j], adu
                open_slaves.add(slave)
                deadline = min(deadline, t_ends[j] + timeout)
            elif shape & FITS_RESPONSE:
                role[position] = RESPONSE
                if self._asked:  # before the first request: its request preceded the recording
                    flags[position] = UNEXPECTED

    def _settle_pairs(self, settled: SettledRuns, k: int, pairs: int, first: int) -> None:
        """The ``pairs`` requests and answers, alternating, from active frame ``k`` on, from a state
        with nothing open: the retries and what is learned now, their columns at the end of the batch."""
        if self._failed:
            self._settle_retries(settled.frames, settled.active[k : k + 2 * pairs : 2], first)
        self._asked = True
        settled.runs.append((k, pairs))
        self._learn_many(settled.gaps[k : k + 2 * pairs : 2])

    def _settle_retries(self, frames: FrameBatch, asks: npt.NDArray[np.intp], first: int) -> None:
        """Of a run of pairs, the first request to each slave whose last request got no valid
        answer: a retry if it repeats that request byte for byte; its valid answer (every
        answer of a run is valid) then clears the slave, so later requests are none."""
        offsets, data = frames.offsets, frames.data
        ask_slaves = np.frombuffer(data, np.uint8)[offsets[asks]]
        for slave in list(self._failed):
            found = np.flatnonzero(ask_slaves == slave)
            if len(found):
                ask = int(asks[found[0]])
                if data[int(offsets[ask]) : int(offsets[ask + 1])] == self._failed.pop(slave):
                    self._held.columns["flags"][first + ask] = RETRY

    def _deadline(self) -> float:
        if not self._open.slaves:
            return float("inf")
        return min(self._open.t_end_ns[s] for s in self._open.slaves) + self.timeout_ns

    def _expire(self, now_ns: int) -> None:
        deadline = now_ns - self.timeout_ns
        for slave in list(self._open.slaves):
            if self._open.t_end_ns[slave] < deadline:
                self._fail(slave)

    def _fail(self, slave: int) -> None:
        self._held.columns["flags"][self._open.position[slave]] |= TIMEOUT
        self._failed[slave] = self._open.data[slave]
        self._open.close(slave)

    def _exception(
        self, position: int, slave: int, function: int, shape: int, *, code: int, crc_ok: bool, t_start: int
    ) -> None:
        columns = self._held.columns
        if not shape & FITS_RESPONSE:
            return
        columns["role"][position] = EXCEPTION
        columns["exception_code"][position] = code
        requests = self._open
        if slave != BROADCAST_ADDRESS and requests.position[slave] != NONE and requests.function[slave] == function:
            self._answer(position, slave, crc_ok, t_start)
        elif self._asked:
            columns["flags"][position] = UNEXPECTED

    def _broadcast(self, position: int, raw: int, shape: int, keys: tuple[int, int], times: tuple[int, int]) -> None:
        """A frame to address 0 (``keys``: its request and response keys; ``times``: its start and end)."""
        columns = self._held.columns
        last = self._last_broadcast
        replies = bool(shape & FITS_RESPONSE) and last is not None and last[:2] == (raw, keys[1]) \
            and times[0] - last[2] <= self._least_timeout_ns
        if shape & FITS_REQUEST and not replies:
            self._last_broadcast = (raw, keys[0], times[1])
            columns["role"][position] = BROADCAST
            self._asked = True
        elif shape & FITS_RESPONSE:
            columns["role"][position] = RESPONSE
            columns["flags"][position] = UNEXPECTED

    def _answer(self, position: int, slave: int, crc_ok: bool, t_start: int) -> None:
        columns, requests = self._held.columns, self._open
        latency = max(0, t_start - requests.t_end_ns[slave])
        columns["request_index"][position] = requests.index[slave]
        columns["latency_ns"][position] = latency
        data = requests.data[slave]
        requests.close(slave)
        if crc_ok:
            self._failed.pop(slave, None)
            self._learn_one(latency)
        else:
            # The master saw no valid answer: its repeat is a retry.
            self._failed[slave] = data

    def _learn_one(self, latency: int) -> None:
        """``_learn_many([latency])``, for the answers the loop visits one by one."""
        self._learned += 1
        self._latencies.append(latency)
        if self._learned < LEARN_EVERY or self._learned % LEARN_EVERY == 0:
            self._adaptive_timeout_ns = _derived_timeout_ns(max(self._latencies))

    def _learn_many(self, latencies: npt.NDArray[np.int64]) -> None:
        """Derive the timeout from the longest recent latency: after every answer at first,
        then every ``LEARN_EVERY`` answers, as the window stood then. Only the last of those
        checkpoints counts, and only the last ``LATENCY_WINDOW`` latencies before it."""
        before = self._learned
        self._learned += len(latencies)
        first_ones = min(self._learned, LEARN_EVERY - 1)
        last = max(first_ones if first_ones > before else 0, self._learned - self._learned % LEARN_EVERY)
        if last > before:
            upto = last - before  # these answers up to the checkpoint's
            longest = int(latencies[max(upto - LATENCY_WINDOW, 0) : upto].max())
            earlier = LATENCY_WINDOW - upto  # the window's part before these answers
            if earlier > 0 and self._latencies:
                skipped = max(len(self._latencies) - earlier, 0)
                longest = max(longest, *itertools.islice(self._latencies, skipped, None))
            self._adaptive_timeout_ns = _derived_timeout_ns(longest)
        self._latencies.extend(latencies[-LATENCY_WINDOW:].tolist())


def _derived_timeout_ns(longest_ns: int) -> int:
    """The response timeout derived from the longest recent latency (see the module docstring)."""
    return min(MAX_TIMEOUT_NS, max(MIN_TIMEOUT_NS, TIMEOUT_PER_LATENCY * longest_ns))


def _defaults(frames: FrameBatch, shapes: Shapes) -> dict[str, npt.NDArray[np.int64]]:
    """Columns before any decision: noise is noise, everything else unknown."""
    count = len(frames)
    lengths = np.diff(frames.offsets)
    noise = frames.is_noise
    raw = shapes.function
    return {
        "role": np.where(noise, NOISE, UNKNOWN).astype(np.int64),
        "slave": np.where(noise, NONE, shapes.slave).astype(np.int64),
        "function": np.where(noise | (lengths < 2), NONE, raw & ~EXCEPTION_BIT).astype(np.int64),
        "exception_code": np.full(count, NONE, np.int64),
        "flags": np.zeros(count, np.int64),
        "request_index": np.full(count, NONE, np.int64),
        "latency_ns": np.full(count, NONE, np.int64),
    }


def _empty_batch() -> MessageBatch:
    held = _Held()
    held.extend(_no_frames(), {name: np.zeros(0, np.int64) for name in _COLUMNS})
    return held.take(0)


def _no_frames() -> FrameBatch:
    return FrameBatch(
        0, b"", np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.bool_),
        np.zeros(0, np.uint16), np.zeros(0, np.bool_), np.zeros(0, np.int64),
    )
