"""Findings: what is wrong on the bus, in words an engineer acts on.

:class:`Evidence` follows a capture batch by batch (frames, roles, pairing and flags, in
columns; the few flagged frames one by one) and keeps, in bounded memory, what the rules below
weigh. :func:`diagnose` turns it and the capture's :class:`~decoders.stats.Statistics` into
findings, each with a severity, one plain sentence, its evidence (counts, the first frames by
index) and the usual causes to check. Severities: ``error`` (traffic is lost), ``warning``
(traffic suffers or will), ``info`` (worth knowing).

The rules and their weights, in one place:

* **silent slave** (error): a slave asked at least ``SILENT_REQUESTS`` times that never
  answered. **Rare answers** (warning): at least ``RARE_REQUESTS`` requests and fewer than
  ``RARE_SHARE`` of them answered.
* **refused requests** (warning): exceptions 01 (illegal function) or 02 (illegal data address)
  by function and addresses, while the slave answers other requests: the master asks for what
  the device lacks; and writes refused with any exception (a command or a value it would not take).
* **late answers** (warning): at least ``LATE_ANSWERS`` answers that come after the master has
  moved on: paired with a request the master followed with another before the answer came, or
  answering nobody after a request of the same slave that timed out. The master gave up before
  the slave answered; the slave's latency and the master's wait are both given.
* **two masters** (warning): at least ``TWO_MASTERS_OVERLAPS`` such answers whose requests were
  followed by another request after waits that differ: the shortest below ``TWO_MASTERS_SPREAD``
  × their median. One master with a short timeout moves on after the same wait each time; a
  second master asks whenever its own cycle says, in the first one's turn. Said instead of the
  late answers it explains.
* **CRC errors** (warning from ``CRC_WARNING_SHARE`` of the frames or ``CRC_WARNING_COUNT``
  errors, info below): said concentrated on one slave or on one direction where at least
  ``CONCENTRATED`` of them are, in bursts where at least ``CONCENTRATED`` fall within
  ``BURST_NS`` of another; with the bit-level difference against the good retry where there is
  one.
* **glitch bytes** (warning): at least ``GLITCHES`` noise records of one or two bytes, all 0x00
  or 0xFF, within ``ADJACENT_T35`` × t3.5 before or after one transmitter's frames.
* **gaps inside frames** and **short silences** (warning): ``gap_1_5`` and ``short_idle``
  frames, by transmitter (the master, or slave N).
* **polling stalls** (warning): a request of one slave and function, polled at least
  ``STALL_POLLS`` times, not repeated for ``STALL_TIMES`` × its usual period and at least
  ``STALL_NS`` (the poll period of ``stats``: between repeats of the same request), or stopped
  that long before the capture's end.
* **busy bus** (warning): a bus load of at least ``BUSY_LOAD``, on a bus with requests.
* **unconfirmed broadcasts** (info): broadcast writes, which no slave answers.
* **a drive in fault** (error): a state word a profile names (ETA) in a state whose name says
  fault (not a fault reset), where the frames are decoded (the report, the live view).
* **written, read back otherwise** (warning): a parameter a profile names, written (FC 6, 16)
  and confirmed by the slave, whose last read before the next write of it gives another value
  (the drive clamped or ignored it, or something else writes it). Where the frames are decoded;
  the write and its answer in one batch.

Exact timing only for the rules of silences and glitch bytes (host read times do not show
them). A clean capture gives no finding: the tests hold every rule to a capture that shows its
symptom and to one that does not, and to the clean samples and real recordings.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from decoders.damage import RetryDiff
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameFlag
from decoders.health import slave_health
from decoders.message import NONE, ROLE_CODE, MessageBatch, ParamValue, Role
from decoders.modbus.codes import exception_name, function_name
from decoders.stats import Statistics

SILENT_REQUESTS = 3
RARE_REQUESTS = 10
RARE_SHARE = 0.5
LATE_ANSWERS = 2
CRC_WARNING_SHARE = 0.01
CRC_WARNING_COUNT = 3
CONCENTRATED = 0.8
BURST_NS = 1_000_000_000
GLITCHES = 2
ADJACENT_T35 = 2
STALL_POLLS = 10
STALL_TIMES = 10
STALL_NS = 1_000_000_000
BUSY_LOAD = 0.7
TWO_MASTERS_OVERLAPS = 5
TWO_MASTERS_SPREAD = 0.5
#: First frames kept as evidence per finding.
FIRST = 5
#: CRC errors whose times are kept to find bursts.
CRC_TIMES = 10_000

_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION, _NOISE = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION], ROLE_CODE[Role.NOISE]
#: Function codes whose request's bytes 2–3 are the first address.
_ADDRESSED = frozenset({1, 2, 3, 4, 5, 6, 15, 16, 23})
_WRITES = frozenset({5, 6, 15, 16, 23})
#: Writes whose request holds the values written, and reads whose answer holds the values read.
_WRITTEN, _READ = frozenset({6, 16}), frozenset({3, 4, 23})
#: Those whose request's bytes 4–5 are a count of addresses (FC 23: the count read).
_COUNTED = frozenset({1, 2, 3, 4, 15, 16, 23})


@dataclass(frozen=True)
class Finding:
    rule: str
    severity: str
    sentence: str
    #: The slave it is about, where it is about one.
    slave: int | None = None
    evidence: dict[str, int | float | str] = field(default_factory=dict)
    #: The first frames that show it, by index.
    frames: tuple[int, ...] = ()
    causes: tuple[str, ...] = ()
    #: The anomaly kinds whose frames show it (the report links to them).
    kinds: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {"rule": self.rule, "severity": self.severity, "slave": self.slave, "sentence": self.sentence,
                "evidence": self.evidence, "frames": list(self.frames), "causes": list(self.causes),
                "kinds": list(self.kinds)}


def _asking(role: npt.NDArray[np.uint8]) -> npt.NDArray[np.bool_]:
    """Requests and broadcasts (two comparisons: ``np.isin`` sorts, five times as long)."""
    asking: npt.NDArray[np.bool_] = (role == _REQUEST) | (role == _BROADCAST)
    return asking


def _answering(role: npt.NDArray[np.uint8]) -> npt.NDArray[np.bool_]:
    answering: npt.NDArray[np.bool_] = (role == _RESPONSE) | (role == _EXCEPTION)
    return answering


def _transmitter(role: int, slave: int) -> str | None:
    if role in (_REQUEST, _BROADCAST):
        return "master"
    if role in (_RESPONSE, _EXCEPTION) and slave != NONE:
        return f"slave {slave}"
    return None


@dataclass
class _Seen:
    """How often something was seen, and the first frames that showed it."""

    count: int = 0
    frames: list[int] = field(default_factory=list)

    def add(self, index: int) -> None:
        self.count += 1
        if len(self.frames) < FIRST:
            self.frames.append(index)


@dataclass(frozen=True)
class _Word:
    """A parameter's word as one frame holds it: raw, the frame's index, and the value as the
    profile says it."""

    raw: int
    index: int
    said: str

    @classmethod
    def of(cls, param: ParamValue, index: int) -> _Word:
        said = "" if param.value is None else f"{param.value}{f' {param.unit}' if param.unit else ''}"
        return cls(param.raw or 0, index, said)


def _tally(found: dict[tuple[int, str], tuple[tuple[_Word, _Word], int]], key: tuple[int, str], written: _Word,
           read: _Word | None) -> None:
    """A write read back otherwise counted in ``found`` (the first such kept)."""
    if read is not None and read.raw != written.raw:
        first, count = found.get(key, ((written, read), 0))
        found[key] = (first, count + 1)


class Evidence:
    """What the rules weigh, gathered batch by batch (see the module docstring)."""

    def __init__(self, t3_5_ns: int, exact: bool) -> None:
        self._adjacent_ns = ADJACENT_T35 * t3_5_ns
        self._exact = exact
        self.timeouts: defaultdict[int, _Seen] = defaultdict(_Seen)
        #: By slave, function, exception code and first address (where the request was seen).
        self.refused: defaultdict[tuple[int, int, int, tuple[int, int] | None], _Seen] = defaultdict(_Seen)
        self.crc_by_slave: defaultdict[int, _Seen] = defaultdict(_Seen)
        self.crc_by_direction: defaultdict[str, _Seen] = defaultdict(_Seen)
        self.late_frames: defaultdict[int, _Seen] = defaultdict(_Seen)
        #: By transmitter, side (before or after its frame) and the bytes.
        self.glitches: defaultdict[tuple[str, str, str], _Seen] = defaultdict(_Seen)
        #: By flag (``gap_1_5``, ``short_idle``) and transmitter.
        self.timing: defaultdict[tuple[str, str], _Seen] = defaultdict(_Seen)
        self.sent: Counter[str] = Counter()
        #: State words a profile names in a fault state, by slave, code and state: the first value.
        self.faults: defaultdict[tuple[int, str, str], _Seen] = defaultdict(_Seen)
        self.fault_raw: dict[tuple[int, str, str], int] = {}
        #: By slave and parameter code: the last confirmed write, and the last read since.
        self._written: dict[tuple[int, str], tuple[_Word, _Word | None]] = {}
        #: Parameters read back otherwise than written: the first such write and read, and how
        #: many writes were.
        self.read_back: dict[tuple[int, str], tuple[tuple[_Word, _Word], int]] = {}

        self.crc_times: list[int] = []
        self.late: defaultdict[int, list[tuple[int, int]]] = defaultdict(list)
        #: By slave and function (``slave << 8 | function``): the last request's time (``NONE``: none).
        self.last_polled_ns = np.full(1 << 16, NONE, np.int64)
        self.last_ns: int | None = None
        #: Per slave, its last timed-out request: (end, index, when the master sent its next request).
        self._timed_out: dict[int, tuple[int, int, int]] = {}
        self._previous: tuple[int, str | None] | None = None  # the last frame's end and transmitter
        self._retries = RetryDiff()
        #: The first damaged answer's difference from its good retry: (the good one's index, the note).
        self.retry_note: tuple[int, str] | None = None

    def add(self, batch: MessageBatch) -> None:
        if not len(batch):
            return
        frames = batch.frames
        first = frames.first_index
        role, slave, flags = batch.role, batch.slave, batch.flags
        self.last_ns = int(frames.t_end_ns[-1])
        self._count_sent(batch)
        self._exceptions(batch)
        self._crc(batch)
        if self.retry_note is None:
            notes = self._retries.notes(batch)
            if notes:
                position = min(notes)
                self.retry_note = (first + position, notes[position])
        self._late(batch)
        self._polls(batch)
        if self._exact:
            for flag, rule in ((FrameFlag.GAP_1_5, "gap_1_5"), (FrameFlag.SHORT_IDLE, "short_idle")):
                for position in np.flatnonzero(flags & flag).tolist():
                    sender = _transmitter(int(role[position]), int(slave[position]))
                    if sender is not None:
                        self.timing[(rule, sender)].add(first + position)
            self._glitches(batch)
        self._previous = (self.last_ns, _transmitter(int(role[-1]), int(slave[-1])))

    def _count_sent(self, batch: MessageBatch) -> None:
        """Frames sent by the master and by each slave (its answers), counted in columns."""
        role = batch.role
        self.sent["master"] += int(np.count_nonzero(_asking(role)))
        answered = batch.slave[_answering(role) & (batch.slave != NONE)]
        counts = np.bincount(answered.astype(np.int64), minlength=0) if len(answered) else np.zeros(0, np.int64)
        for sender_slave in np.flatnonzero(counts).tolist():
            self.sent[f"slave {sender_slave}"] += int(counts[sender_slave])

    def add_decoded(self, batch: AnnotatedBatch) -> None:
        """What the decoded values show (where a view decodes them: the report, the live view):
        a drive's state word, as its profile names it, in a fault state; a parameter written and
        read back otherwise."""
        messages = batch.messages
        answers = np.flatnonzero((messages.role == _RESPONSE) & messages.frames.crc_ok)
        if not len(answers):
            return
        decodings, first = batch.decodings, messages.frames.first_index
        for position in answers.tolist():
            function, slave = int(messages.function[position]), int(messages.slave[position])
            request = int(messages.request_index[position]) - first
            if function in _WRITTEN and request >= 0:
                self._wrote(slave, decodings[request].params, first + request)
            elif function in _READ:
                self._read(slave, decodings[position].params, first + position)
            for param in decodings[position].params:
                if param.code is None or not isinstance(param.value, str) or param.raw is None:
                    continue
                state = param.value.split(", ")[0]
                if "fault" in state and "reset" not in state:
                    key = (int(messages.slave[position]), param.code, state)
                    self.faults[key].add(first + position)
                    self.fault_raw.setdefault(key, param.raw)

    def _wrote(self, slave: int, params: tuple[ParamValue, ...], index: int) -> None:
        for param in params:
            if param.code is not None and param.raw is not None:
                self._settle((slave, param.code))
                self._written[(slave, param.code)] = (_Word.of(param, index), None)

    def _read(self, slave: int, params: tuple[ParamValue, ...], index: int) -> None:
        for param in params:
            if param.code is not None and param.raw is not None and (slave, param.code) in self._written:
                self._written[(slave, param.code)] = (self._written[(slave, param.code)][0], _Word.of(param, index))

    def _settle(self, key: tuple[int, str]) -> None:
        """The last read since the last write of ``key``: another value is a parameter read back
        otherwise (a read on its way to the value written counts only if it stays the last)."""
        if key in self._written:
            _tally(self.read_back, key, *self._written[key])

    def read_back_otherwise(self) -> dict[tuple[int, str], tuple[tuple[_Word, _Word], int]]:
        """:attr:`read_back`, with each write not yet followed by another weighed by its last read
        so far."""
        found = dict(self.read_back)
        for key, (written, read) in self._written.items():
            _tally(found, key, written, read)
        return found

    def _exceptions(self, batch: MessageBatch) -> None:
        first, frames = batch.frames.first_index, batch.frames
        code = batch.exception_code
        # Reads refused as 01/02 (what the device lacks); writes refused with any code (a command
        # or a value the device would not take).
        functions = batch.function & 0x7F
        written = np.isin(functions, sorted(_WRITES))
        refused = np.flatnonzero((batch.role == _EXCEPTION) & ((code == 1) | (code == 2) | written))
        for position in refused.tolist():
            function, request = int(batch.function[position]) & 0x7F, int(batch.request_index[position])
            addresses = None
            at = request - first
            if function in _ADDRESSED and request != NONE and at >= 0:
                start = int(frames.offsets[at])
                address = int.from_bytes(frames.data[start + 2 : start + 4], "big")
                count = int.from_bytes(frames.data[start + 4 : start + 6], "big") if function in _COUNTED else 1
                addresses = (address, address + max(count, 1) - 1)
            key = (int(batch.slave[position]), function, int(batch.exception_code[position]), addresses)
            self.refused[key].add(first + position)

    def _crc(self, batch: MessageBatch) -> None:
        frames = batch.frames
        broken = np.flatnonzero(~frames.crc_ok & (batch.role != _NOISE))
        for position in broken.tolist():
            role, slave = int(batch.role[position]), int(batch.slave[position])
            direction = "requests" if role in (_REQUEST, _BROADCAST) else "answers"
            self.crc_by_slave[slave].add(frames.first_index + position)
            self.crc_by_direction[direction].add(frames.first_index + position)
            if len(self.crc_times) < CRC_TIMES:
                self.crc_times.append(int(frames.t_start_ns[position]))

    def _late(self, batch: MessageBatch) -> None:
        """Answers that come after the master has moved on: paired with a request the master
        followed with another before the answer came, or answering nobody after a request of the
        same slave that timed out."""
        frames, role, first = batch.frames, batch.role, batch.frames.first_index
        requests = np.flatnonzero(_asking(role))
        answers = np.flatnonzero(_answering(role))
        asked = batch.request_index[answers] - first
        paired = (batch.request_index[answers] != NONE) & (asked >= 0)
        answers, asked = answers[paired], asked[paired]
        following = np.searchsorted(requests, asked, "right")
        exists = following < len(requests)
        nxt = requests[np.minimum(following, max(len(requests) - 1, 0))] if len(requests) else following
        for position, request, moved in zip(answers[exists & (nxt < answers)].tolist(),
                                            asked[exists & (nxt < answers)].tolist(),
                                            nxt[exists & (nxt < answers)].tolist(), strict=True):
            ended = int(frames.t_end_ns[request])
            self._late_answer(int(batch.slave[position]), first + position,
                              int(frames.t_start_ns[position]) - ended, int(frames.t_start_ns[moved]) - ended)
        self._unpaired_late(batch, requests)

    def _unpaired_late(self, batch: MessageBatch, requests: np.ndarray) -> None:
        frames, flags, first = batch.frames, batch.flags, batch.frames.first_index
        timed_out = np.flatnonzero((flags & FrameFlag.TIMEOUT) != 0)
        answering = _answering(batch.role)
        unexpected = np.flatnonzero(((flags & FrameFlag.UNEXPECTED) != 0) & answering)
        for position, kind in sorted([(p, 0) for p in timed_out.tolist()] + [(p, 1) for p in unexpected.tolist()]):
            slave = int(batch.slave[position])
            if kind == 0:
                self.timeouts[slave].add(first + position)
                later = requests[np.searchsorted(requests, position, "right"):]
                moved_on = int(frames.t_start_ns[later[0]]) if len(later) else -1
                self._timed_out[slave] = (int(frames.t_end_ns[position]), first + position, moved_on)
                continue
            before = self._timed_out.pop(slave, None)
            if before is not None and before[2] >= 0:
                ended, _, moved_on = before
                self._late_answer(slave, first + position, int(frames.t_start_ns[position]) - ended, moved_on - ended)

    def _late_answer(self, slave: int, index: int, latency_ns: int, waited_ns: int) -> None:
        if latency_ns > waited_ns:
            if len(self.late[slave]) < 1000:
                self.late[slave].append((latency_ns, waited_ns))
            self.late_frames[slave].add(index)

    def _polls(self, batch: MessageBatch) -> None:
        """Per slave and function, the last request's time (a request's time laid on
        its key's place in order: the batch's last one stays)."""
        requests = np.flatnonzero((batch.role == _REQUEST) & (batch.slave >= 0) & (batch.function >= 0))
        keys = (batch.slave[requests].astype(np.int64) << 8) | batch.function[requests].astype(np.int64)
        self.last_polled_ns[keys] = batch.frames.t_start_ns[requests]

    def _glitches(self, batch: MessageBatch) -> None:
        """Noise of one or two bytes, all 0x00 or 0xFF, within two t3.5 of a transmitter's frame
        (the nearer of the frames before and after it): found in columns, gathered by who sent
        the frame, on which side and the bytes."""
        frames, role, slave = batch.frames, batch.role, batch.slave
        starts, lengths = frames.offsets[:-1], np.diff(frames.offsets)
        raw = np.frombuffer(frames.data, np.uint8)
        candidates = np.flatnonzero((role == _NOISE) & (lengths <= 2) & (lengths > 0))
        head, tail = raw[starts[candidates]], raw[starts[candidates] + lengths[candidates] - 1]
        candidates = candidates[((head == 0) | (head == 0xFF)) & ((tail == 0) | (tail == 0xFF))]
        if not len(candidates):
            return
        # Who sent each frame: -1 the master, N slave N, -2 nobody (noise, an unknown frame).
        sender = np.where(_asking(role), -1, np.where(_answering(role) & (slave != NONE), slave, -2))
        count = len(batch)
        later, earlier = np.minimum(candidates + 1, count - 1), np.maximum(candidates - 1, 0)
        gap_before = np.where(candidates + 1 < count, frames.t_start_ns[later] - frames.t_end_ns[candidates], -1)
        gap_after = np.where(candidates > 0, frames.t_start_ns[candidates] - frames.t_end_ns[earlier], -1)
        if self._previous is not None and candidates[0] == 0 and self._previous[1] is not None:
            gap_after[0] = int(frames.t_start_ns[0]) - self._previous[0]
        limit = self._adjacent_ns
        before_ok = (gap_before >= 0) & (gap_before <= limit) & (sender[later] != -2)
        after_ok = (gap_after >= 0) & (gap_after <= limit) & ((sender[earlier] != -2) | (candidates == 0))
        take_before = before_ok & (~after_ok | (gap_before <= gap_after))
        chosen = take_before | after_ok
        who = np.where(take_before, sender[later], sender[earlier])
        for position, side_before, whom in zip(candidates[chosen].tolist(), take_before[chosen].tolist(),
                                               who[chosen].tolist(), strict=True):
            if position == 0 and not side_before:
                name = self._previous[1] if self._previous is not None else None
            else:
                name = "master" if whom == -1 else f"slave {whom}"
            if name is None:
                continue
            data = frames.data[int(starts[position]) : int(starts[position]) + int(lengths[position])]
            self.glitches[(name, "before" if side_before else "after", data.hex())].add(frames.first_index + position)


def diagnose(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    """The findings, errors first, each rule's in order of its evidence."""
    overlapping = _two_masters(evidence)
    found = [*_silent(statistics, evidence), *_faults(evidence), *_refused(statistics, evidence),
             *(overlapping or _late(evidence)), *_read_back(evidence),
             *_crc(statistics, evidence), *_glitches(evidence), *_timing(evidence), *_stalls(statistics, evidence),
             *_busy(statistics), *_broadcasts(statistics)]
    order = {"error": 0, "warning": 1, "info": 2}
    return sorted(found, key=lambda f: order[f.severity])


def _who(senders: list[str]) -> str:
    """``slave 3``, ``slaves 3 and 9``, ``slaves 1–16``, ``the master and slave 2``: a list said
    as short as it reads (runs of three or more numbers as a range)."""
    numbers = sorted(int(sender.split()[1]) for sender in senders if sender != "master")
    runs: list[list[int]] = []
    for number in numbers:
        if runs and number == runs[-1][-1] + 1:
            runs[-1].append(number)
        else:
            runs.append([number])
    parts = [f"{run[0]}–{run[-1]}" if len(run) >= 3 else ", ".join(map(str, run)) for run in runs]
    said = ("slave " if len(numbers) == 1 else "slaves ") + _joined(parts) if numbers else ""
    return _joined([*(["the master"] if "master" in senders else []), *([said] if said else [])])


def _joined(parts: list[str]) -> str:
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1] if parts else ""


def _first(frames: list[int]) -> tuple[int, ...]:
    return tuple(sorted(frames)[:FIRST])


def _silent(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    silent: list[tuple[int, int]] = []
    rare: list[tuple[int, int, int]] = []
    for health in slave_health(statistics):
        if health.slave == 0 or health.requests < SILENT_REQUESTS:
            continue
        answered = health.responses + sum(health.exceptions.values())
        if answered == 0:
            silent.append((health.slave, health.requests))
        elif health.requests >= RARE_REQUESTS and answered < RARE_SHARE * health.requests:
            rare.append((health.slave, answered, health.requests))
    causes = ("the slave address set on the device", "its line settings (baud, parity, stop bits)",
              "the wiring to it (A/B swapped, a loose terminal)", "its power")

    def frames(slaves: list[int]) -> tuple[int, ...]:
        return _first([i for slave in slaves if slave in evidence.timeouts for i in evidence.timeouts[slave].frames])

    found = []
    if silent:
        slaves = [slave for slave, _ in silent]
        asked = sum(requests for _, requests in silent)
        who = _who([f"slave {slave}" for slave in slaves])
        found.append(Finding("silent_slave", "error", f"{who[0].upper()}{who[1:]} never answered: {asked} "
                             "requests, no answer.", slaves[0] if len(slaves) == 1 else None,
                             {"slaves": " ".join(map(str, slaves)), "requests": asked, "answers": 0},
                             frames(slaves), causes, ("timeout",)))
    for slave, answered, requests in rare:
        found.append(Finding("rare_answers", "warning", f"Slave {slave} answered only {answered} of {requests} "
                             f"requests ({answered / requests:.0%}).", slave,
                             {"requests": requests, "answers": answered}, frames([slave]), causes, ("timeout",)))
    return found


def _refused(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    """By function, exception and addresses, the slaves that refuse them."""
    groups: defaultdict[tuple[int, int, tuple[int, int] | None], list[tuple[int, _Seen]]] = defaultdict(list)
    for (slave, function, code, addresses), seen in evidence.refused.items():
        groups[(function, code, addresses)].append((slave, seen))
    answered = Counter[int]()
    for (slave, _), stats in statistics.per_function.items():
        answered[slave] += stats.responses
    found = []
    for (function, code, addresses), slaves in sorted(groups.items(), key=lambda item: str(item[0])):
        count = sum(seen.count for _, seen in slaves)
        names = [slave for slave, _ in sorted(slaves)]
        who = _who([f"slave {slave}" for slave in names])
        where = "" if addresses is None else (f" at address {addresses[0]}" if addresses[0] == addresses[1] else
                                              f" at addresses {addresses[0]}..{addresses[1]}")
        others = sum(answered[slave] for slave in names)
        also = (f", while {'it answers' if len(names) == 1 else 'they answer'} {others} other "
                f"request{'s' if others != 1 else ''}") if others else ""
        found.append(Finding(
            "refused_requests", "warning",
            f"{who[0].upper()}{who[1:]} refuse{'s' if len(names) == 1 else ''} FC {function} "
            f"({function_name(function)}){where}: exception {code:02d} ({exception_name(code)}), {count}×{also}.",
            names[0] if len(names) == 1 else None,
            {"function": function, "exception": code, "count": count, "slaves": " ".join(map(str, names)),
             **({"first_address": addresses[0], "last_address": addresses[1]} if addresses is not None else {})},
            _first([i for _, seen in slaves for i in seen.frames]),
            ("the master asks for what this device lacks: its model, options or firmware",
             "an address off by one (a manual's 1-based or 40001 numbering)", "a profile for another device",
             *(("a value out of range, or a command the device's state does not allow (exception 03, 04)",)
               if function in _WRITES else ())),
            ("exception",)))
    return found


def _faults(evidence: Evidence) -> list[Finding]:
    """A drive's state word in a fault state, as its profile names the states."""
    found = []
    for (slave, code, state), seen in sorted(evidence.faults.items()):
        raw = evidence.fault_raw[(slave, code, state)]
        found.append(Finding(
            "drive_fault", "error",
            f"Slave {slave} reports {code} = 16#{raw:04X}: {state} "
            f"({'once' if seen.count == 1 else f'{seen.count}×'}).",
            slave, {"code": code, "state": state, "raw": raw, "count": seen.count}, tuple(seen.frames),
            ("the drive's own fault code (its last-fault parameter, its display)", "what the drive was commanded just "
             "before (the control word written)", "the drive's supply and the motor"), ()))
    return found


def _late(evidence: Evidence) -> list[Finding]:
    found = []
    for slave, pairs in sorted(evidence.late.items()):
        if len(pairs) < LATE_ANSWERS:
            continue
        # The medians of the first answers kept; the count of every one.
        latency = float(np.median([p[0] for p in pairs])) / 1e6
        wait = float(np.median([p[1] for p in pairs])) / 1e6
        count = evidence.late_frames[slave].count
        found.append(Finding(
            "late_answers", "warning",
            f"Slave {slave} answers after the master has moved on: its answers come {latency:.1f} ms after the "
            f"request, the master waits {wait:.1f} ms ({count} answers too late).", slave,
            {"late_answers": count, "slave_latency_ms": round(latency, 3), "master_wait_ms": round(wait, 3)},
            tuple(evidence.late_frames[slave].frames),
            ("the master's response timeout is shorter than the slave's answer time: raise it",
             "the slave is busy (a long scan, a parameter being saved)"), ("unexpected", "timeout")))
    return found


def _two_masters(evidence: Evidence) -> list[Finding]:
    """Answers after another request, whose requests were followed after waits that differ."""
    waits = sorted(wait for pairs in evidence.late.values() for _, wait in pairs)
    if len(waits) < TWO_MASTERS_OVERLAPS:
        return []
    middle = float(np.median(waits))
    if waits[0] >= TWO_MASTERS_SPREAD * middle:
        return []
    count = sum(seen.count for seen in evidence.late_frames.values())
    slaves = sorted(evidence.late)
    shortest, median, longest = waits[0] / 1e6, middle / 1e6, waits[-1] / 1e6
    return [Finding(
        "two_masters", "warning",
        f"Two masters seem to share the bus: {count} answers of {_who([f'slave {s}' for s in slaves])} came after "
        f"another request, sent {shortest:.1f} to {longest:.1f} ms after theirs (one master with a short timeout "
        "would wait the same each time).", slaves[0] if len(slaves) == 1 else None,
        {"overlaps": count, "slaves": " ".join(map(str, slaves)), "shortest_wait_ms": round(shortest, 3),
         "median_wait_ms": round(median, 3), "longest_wait_ms": round(longest, 3)},
        _first([i for seen in evidence.late_frames.values() for i in seen.frames]),
        ("a second master on the line (an HMI, a PLC, a commissioning PC, a gateway): one master per line",
         "a gateway that forwards requests of several clients without waiting for the answers"),
        ("unexpected", "timeout"))]


def _read_back(evidence: Evidence) -> list[Finding]:
    found = []
    for (slave, code), ((written, read), count) in sorted(evidence.read_back_otherwise().items()):
        found.append(Finding(
            "read_back_otherwise", "warning",
            f"Slave {slave}'s {code} was written {_said(written)} and reads back {_said(read)}"
            f"{f' ({count} writes so)' if count > 1 else ''}.",
            slave, {"code": code, "written": written.raw, "read": read.raw, "count": count},
            (written.index, read.index),
            ("the value is out of the parameter's range or step, and the drive clamped it",
             "the drive's state or access level ignores the write (a running motor, a locked menu)",
             "another master or the drive's keypad writes it too"), ()))
    return found


def _said(word: _Word) -> str:
    return f"16#{word.raw:04X}" + (f" ({word.said})" if word.said else "")


def _crc(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    total = statistics.crc_errors
    if not total:
        return []
    share = total / max(statistics.frames, 1)  # of every frame, as the report's bus card counts
    severity = "warning" if share >= CRC_WARNING_SHARE or total >= CRC_WARNING_COUNT else "info"
    by_slave = {slave: seen.count for slave, seen in evidence.crc_by_slave.items()}
    by_direction = {direction: seen.count for direction, seen in evidence.crc_by_direction.items()}
    parts = []
    slave, most = max(by_slave.items(), key=lambda item: item[1])
    if (len(by_slave) > 1 and most >= CONCENTRATED * total) or (len(by_slave) == 1 and total >= CRC_WARNING_COUNT):
        parts.append(f"{most} of them from or to slave {slave}")
    direction, most_way = max(by_direction.items(), key=lambda item: item[1])
    if total >= CRC_WARNING_COUNT and most_way >= CONCENTRATED * total:
        parts.append(f"{most_way} on the {'master' if direction == 'requests' else 'slaves'}' {direction}")
    times = np.array(sorted(evidence.crc_times), np.int64)
    close = np.diff(times) <= BURST_NS if len(times) > 1 else np.zeros(0, np.bool_)
    in_bursts = int(np.count_nonzero(np.concatenate([[False], close]) | np.concatenate([close, [False]])))
    if total >= CRC_WARNING_COUNT and in_bursts >= CONCENTRATED * len(times):
        parts.append(f"{in_bursts} in bursts (within {BURST_NS // 1_000_000_000} s of each other)")
    said = f": {'; '.join(parts)}" if parts else ""
    if evidence.retry_note is not None:
        said += f"; frame #{evidence.retry_note[0]} is the {evidence.retry_note[1]}"
    frames = tuple(sorted(i for seen in evidence.crc_by_slave.values() for i in seen.frames)[:FIRST])
    return [Finding(
        "crc_errors", severity, f"{total} frame{'s' if total != 1 else ''} with a CRC error ({share:.2%} of the "
        f"frames){said}.", slave if parts and parts[0].endswith(f"slave {slave}") else None,
        {"crc_errors": total, "share": round(share, 5), "in_bursts": in_bursts},
        frames,
        ("the cable: shield, twisted pair, length, stubs", "termination (120 Ω at both ends only) and bias",
         "a noise source near the line or the device (a drive's motor cable)",
         "two transmitters at once (a second master, a device answering for another's address)"),
        ("crc_error",))]


def _glitches(evidence: Evidence) -> list[Finding]:
    """By side and bytes, the transmitters with at least ``GLITCHES`` of them."""
    groups: defaultdict[tuple[str, str], list[tuple[str, _Seen]]] = defaultdict(list)
    for (sender, side, data), seen in evidence.glitches.items():
        if seen.count >= GLITCHES:
            groups[(side, data)].append((sender, seen))
    found = []
    for (side, data), senders in sorted(groups.items()):
        count = sum(seen.count for _, seen in senders)
        names = [sender for sender, _ in senders]
        byte = " ".join(f"0x{data[i:i + 2].upper()}" for i in range(0, len(data), 2))
        found.append(Finding(
            "glitch_bytes", "warning",
            f"A stray {byte} {'comes before' if side == 'before' else 'follows'} the frames of {_who(names)} "
            f"({count}×).", _single_slave(names),
            {"transmitters": ", ".join(sorted(names)), "side": side, "count": count},
            _first([i for _, seen in senders for i in seen.frames]),
            ("the transmitter's driver enable switching too early or too late",
             "missing bias resistors: the idle line floats", "missing or extra termination"), ("noise",)))
    return found


def _single_slave(senders: list[str]) -> int | None:
    return int(senders[0].split()[1]) if len(senders) == 1 and senders[0] != "master" else None


def _timing(evidence: Evidence) -> list[Finding]:
    """By flag, the transmitters whose frames show it."""
    texts = {"gap_1_5": ("gaps of more than 1.5 characters inside {n} of {their} {sent} frames",
                         ("a transmitter that pauses inside a frame: a slow or busy device, a USB-RS485 "
                          "converter on the transmitting side", "a gateway that forwards in pieces")),
             "short_idle": ("less than 3.5 characters of silence before {n} of {their} {sent} frames",
                            ("a device that answers or sends too soon after the last frame",
                             "a master polling faster than the line's t3.5"))}
    groups: defaultdict[str, list[tuple[str, _Seen]]] = defaultdict(list)
    for (rule, sender), seen in evidence.timing.items():
        groups[rule].append((sender, seen))
    found = []
    for rule, senders in sorted(groups.items()):
        text, causes = texts[rule]
        names = [sender for sender, _ in senders]
        count = sum(seen.count for _, seen in senders)
        sent = sum(evidence.sent[sender] for sender in names)
        who = _who(names)
        verb = "sends" if len(names) == 1 else "send"
        their = "its" if len(names) == 1 else "their"
        found.append(Finding(
            rule, "warning", f"{who[0].upper()}{who[1:]} {verb} " + text.format(n=count, their=their, sent=sent) + ".",
            _single_slave(names), {"transmitters": ", ".join(sorted(names)), "count": count, "frames_sent": sent},
            _first([i for _, seen in senders for i in seen.frames]), causes, (rule,)))
    return found


def _stalls(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    """From each slave and function's poll period (the time between repeats of the same request,
    as ``stats`` measures it): its longest against its usual, and the wait since the last one.
    One finding each for the stalls and the stops, the worst named first."""
    stalls: list[tuple[float, str, dict[str, int | float | str]]] = []
    stops: list[tuple[float, str, dict[str, int | float | str]]] = []
    for (slave, function), stats in sorted(statistics.per_function.items()):
        usual, longest = stats.poll_period.percentile(50), stats.poll_period.maximum
        key = slave << 8 | function
        if stats.poll_period.count < STALL_POLLS or usual is None or usual <= 0 or longest is None:
            continue
        limit = max(STALL_TIMES * usual, STALL_NS)
        last = int(evidence.last_polled_ns[key])
        stopped = (evidence.last_ns or 0) - last if last != NONE else 0
        where = f"slave {slave} FC {function}"
        if longest >= limit:
            stalls.append((longest / usual, f"{where}: usually every {_duration(usual)}, once not for "
                           f"{_duration(longest)}", {"slave": slave, "function": function, "usual_ms":
                                                     round(usual / 1e6, 3), "longest_s": round(longest / 1e9, 3)}))
        elif stopped >= limit:
            stops.append((stopped / usual, f"{where}: every {_duration(usual)}, none for the last "
                          f"{_duration(stopped)}", {"slave": slave, "function": function, "usual_ms":
                                                    round(usual / 1e6, 3), "stopped_s": round(stopped / 1e9, 3)}))
    found = []
    for rule, said, items, causes in (
            ("polling_stalls", "Polling stalled", stalls,
             ("the master busy elsewhere (a PLC scan, an HMI page change)",
              "a communication fault the master handles by pausing", "a gateway's queue")),
            ("polling_stops", "Polling stopped before the capture's end", stops,
             ("the master stopped asking (a fault it handles, a changed page)", "the master lost the line"))):
        if not items:
            continue
        items.sort(key=lambda item: -item[0])
        shown = "; ".join(text for _, text, _ in items[:3]) + (f"; and {len(items) - 3} more" if len(items) > 3 else "")
        pairs = f"{len(items)} slave/function pairs" if len(items) > 1 else "1 slave/function pair"
        about = items[0][2]["slave"] if len(items) == 1 else None
        worst = {f"worst_{name}": value for name, value in items[0][2].items()}
        found.append(Finding(rule, "warning", f"{said} on {pairs}: {shown}.", about if isinstance(about, int) else None,
                             {"pairs": len(items), **worst}, (), causes, ()))
    return found


def _duration(ns: float) -> str:
    return f"{ns / 1e6:.0f} ms" if ns < 10e9 else f"{ns / 1e9:.1f} s"


def _busy(statistics: Statistics) -> list[Finding]:
    load = statistics.bus_load
    # A line of bytes that form no Modbus frame (another protocol, wrong settings) is not a busy bus.
    if load is None or load < BUSY_LOAD or not statistics.roles.get("request"):
        return []
    return [Finding("busy_bus", "warning", f"The bus is busy {load:.0%} of the time: answers wait and polls "
                    "stretch.", None, {"bus_load": round(load, 4)}, (),
                    ("fewer or longer polls (read blocks of registers)", "a higher baud rate",
                     "a slow device holding the line"), ())]


def _broadcasts(statistics: Statistics) -> list[Finding]:
    writes = sum(stats.broadcasts for (slave, function), stats in statistics.per_function.items()
                 if slave == 0 and function in _WRITES)
    if not writes:
        return []
    return [Finding("unconfirmed_broadcasts", "info", f"{writes} broadcast write{'s' if writes != 1 else ''}: no "
                    "slave answers a broadcast, so nothing on the bus confirms them.", 0, {"broadcast_writes": writes},
                    (), ("read the values back from each slave to know they took them",), ())]
