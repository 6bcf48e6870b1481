"""Symptoms: what a capture shows on the way that the findings' rules weigh.

:class:`Symptoms` follows a capture batch by batch (frames, roles, pairing and flags, in
columns; the few flagged frames one by one, and where the frames are decoded, the parameters a
profile names) and keeps, in bounded memory, the counts and first frames of each symptom:
exceptions by function and addresses, late answers and the waits before them, CRC errors and
their times, glitch bytes beside a transmitter's frames, polls and their gaps, drive states,
writes and what was read back. :func:`decoders.findings.diagnose` weighs them; its docstring
states the rules and their weights.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from decoders.damage import RetryDiff
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameFlag
from decoders.message import NONE, ROLE_CODE, MessageBatch, ParamValue, Role

#: Glitch bytes count within this many t3.5 before or after a transmitter's frame.
ADJACENT_T35 = 2
#: First frames kept as evidence per finding.
FIRST = 5
#: CRC errors whose times are kept to find bursts.
CRC_TIMES = 10_000

_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION, _NOISE = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION], ROLE_CODE[Role.NOISE]
#: Function codes whose request's bytes 2–3 are the first address.
_ADDRESSED = frozenset({1, 2, 3, 4, 5, 6, 15, 16, 23})
#: Requests that write.
WRITES = frozenset({5, 6, 15, 16, 23})
#: Writes whose request holds the values written, and reads whose answer holds the values read.
_WRITTEN, _READ = frozenset({6, 16}), frozenset({3, 4, 23})
#: Those whose request's bytes 4–5 are a count of addresses (FC 23: the count read).
_COUNTED = frozenset({1, 2, 3, 4, 15, 16, 23})


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
class Seen:
    """How often something was seen, and the first frames that showed it."""

    count: int = 0
    frames: list[int] = field(default_factory=list)

    def add(self, index: int) -> None:
        self.count += 1
        if len(self.frames) < FIRST:
            self.frames.append(index)


@dataclass(frozen=True)
class Word:
    """A parameter's word as one frame holds it: raw, the frame's index, and the value as the
    profile says it."""

    raw: int
    index: int
    said: str

    @classmethod
    def of(cls, param: ParamValue, index: int) -> Word:
        said = "" if param.value is None else f"{param.value}{f' {param.unit}' if param.unit else ''}"
        return cls(param.raw or 0, index, said)


def _tally(found: dict[tuple[int, str], tuple[tuple[Word, Word], int]], key: tuple[int, str], written: Word,
           read: Word | None) -> None:
    """A write read back otherwise counted in ``found`` (the first such kept)."""
    if read is not None and read.raw != written.raw:
        first, count = found.get(key, ((written, read), 0))
        found[key] = (first, count + 1)


class Symptoms:
    """What the rules weigh, gathered batch by batch (see the module docstring)."""

    def __init__(self, t3_5_ns: int, exact: bool) -> None:
        self._adjacent_ns = ADJACENT_T35 * t3_5_ns
        self._exact = exact
        self.timeouts: defaultdict[int, Seen] = defaultdict(Seen)
        #: By slave, function, exception code and first address (where the request was seen).
        self.refused: defaultdict[tuple[int, int, int, tuple[int, int] | None], Seen] = defaultdict(Seen)
        self.crc_by_slave: defaultdict[int, Seen] = defaultdict(Seen)
        self.crc_by_direction: defaultdict[str, Seen] = defaultdict(Seen)
        self.late_frames: defaultdict[int, Seen] = defaultdict(Seen)
        #: By transmitter, side (before or after its frame) and the bytes.
        self.glitches: defaultdict[tuple[str, str, str], Seen] = defaultdict(Seen)
        #: By flag (``gap_1_5``, ``short_idle``) and transmitter.
        self.timing: defaultdict[tuple[str, str], Seen] = defaultdict(Seen)
        self.sent: Counter[str] = Counter()
        #: State words a profile names in a fault state, by slave, code and state: the first value.
        self.faults: defaultdict[tuple[int, str, str], Seen] = defaultdict(Seen)
        self.fault_raw: dict[tuple[int, str, str], int] = {}
        #: By slave and parameter code: the last confirmed write, and the last read since.
        self._written: dict[tuple[int, str], tuple[Word, Word | None]] = {}
        #: Parameters read back otherwise than written: the first such write and read, and how
        #: many writes were.
        self.read_back: dict[tuple[int, str], tuple[tuple[Word, Word], int]] = {}

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
        params, first = batch.message_params(), messages.frames.first_index
        for position in answers.tolist():
            function, slave = int(messages.function[position]), int(messages.slave[position])
            request = int(messages.request_index[position]) - first
            if function in _WRITTEN and request >= 0:
                self._wrote(slave, params[request], first + request)
            elif function in _READ:
                self._read(slave, params[position], first + position)
            for param in params[position]:
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
                self._written[(slave, param.code)] = (Word.of(param, index), None)

    def _read(self, slave: int, params: tuple[ParamValue, ...], index: int) -> None:
        for param in params:
            if param.code is not None and param.raw is not None and (slave, param.code) in self._written:
                self._written[(slave, param.code)] = (self._written[(slave, param.code)][0], Word.of(param, index))

    def _settle(self, key: tuple[int, str]) -> None:
        """The last read since the last write of ``key``: another value is a parameter read back
        otherwise (a read on its way to the value written counts only if it stays the last)."""
        if key in self._written:
            _tally(self.read_back, key, *self._written[key])

    def read_back_otherwise(self) -> dict[tuple[int, str], tuple[tuple[Word, Word], int]]:
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
        written = np.isin(functions, sorted(WRITES))
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
