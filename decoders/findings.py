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
  by function and first address, while the slave answers other requests: the master asks for
  what the device lacks.
* **late answers** (warning): at least ``LATE_ANSWERS`` answers that come after the master has
  moved on: paired with a request the master followed with another before the answer came, or
  answering nobody after a request of the same slave that timed out. The master gave up before
  the slave answered; the slave's latency and the master's wait are both given.
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
  ``STALL_NS``, or stopped that long before the capture's end.
* **busy bus** (warning): a bus load of at least ``BUSY_LOAD``.
* **unconfirmed broadcasts** (info): broadcast writes, which no slave answers.

Exact timing only for the rules of silences and glitch bytes (host read times do not show
them). A clean capture gives no finding: the tests hold every rule to a capture that shows its
symptom and to one that does not, and to the clean samples and real recordings.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np

from decoders.damage import RetryDiff
from decoders.frame import FrameFlag
from decoders.health import slave_health
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
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
#: First frames kept as evidence per finding.
FIRST = 5
#: CRC errors whose times are kept to find bursts.
CRC_TIMES = 10_000

_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION, _NOISE = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION], ROLE_CODE[Role.NOISE]
#: Function codes whose request's bytes 2–3 are the first address.
_ADDRESSED = frozenset({1, 2, 3, 4, 5, 6, 15, 16, 23})
_WRITES = frozenset({5, 6, 15, 16, 23})
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


@dataclass
class _Poll:
    last_ns: int
    count: int = 1
    longest_ns: int = 0
    longest_at: int = 0  # the frame index after which the longest wait began


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
        self.crc_times: list[int] = []
        self.late: defaultdict[int, list[tuple[int, int]]] = defaultdict(list)
        self.polls: dict[tuple[int, int], _Poll] = {}
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
        self.sent["master"] += int(np.count_nonzero(np.isin(role, (_REQUEST, _BROADCAST))))
        answered = batch.slave[np.isin(role, (_RESPONSE, _EXCEPTION)) & (batch.slave != NONE)]
        counts = np.bincount(answered.astype(np.int64), minlength=0) if len(answered) else np.zeros(0, np.int64)
        for sender_slave in np.flatnonzero(counts).tolist():
            self.sent[f"slave {sender_slave}"] += int(counts[sender_slave])

    def _exceptions(self, batch: MessageBatch) -> None:
        first, frames = batch.frames.first_index, batch.frames
        refused = np.flatnonzero((batch.role == _EXCEPTION) & np.isin(batch.exception_code, (1, 2)))
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
        requests = np.flatnonzero(np.isin(role, (_REQUEST, _BROADCAST)))
        answers = np.flatnonzero(np.isin(role, (_RESPONSE, _EXCEPTION)))
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
        answering = np.isin(batch.role, (_RESPONSE, _EXCEPTION))
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
        """Per slave and function, the longest wait between two requests (and after which), and
        the last request's time: requests ordered by key and time, waits within each key."""
        frames = batch.frames
        requests = np.flatnonzero(batch.role == _REQUEST)
        if not len(requests):
            return
        keys = (batch.slave[requests].astype(np.int64) << 8) | batch.function[requests].astype(np.int64)
        order = np.lexsort((frames.t_start_ns[requests], keys))
        keys, times, positions = keys[order], frames.t_start_ns[requests][order], requests[order]
        starts = np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1]]))
        ends = np.concatenate([starts[1:], [len(keys)]])
        for key, start, end in zip(keys[starts].tolist(), starts.tolist(), ends.tolist(), strict=True):
            poll = self.polls.get((key >> 8, key & 0xFF))
            if poll is None:
                poll = self.polls[(key >> 8, key & 0xFF)] = _Poll(int(times[start]), 0)
            waits = np.diff(times[start:end], prepend=poll.last_ns)
            longest = int(np.argmax(waits))
            if int(waits[longest]) > poll.longest_ns:
                poll.longest_ns = int(waits[longest])
                poll.longest_at = frames.first_index + int(positions[start + longest - 1]) if longest else -1
            poll.last_ns, poll.count = int(times[end - 1]), poll.count + end - start

    def _glitches(self, batch: MessageBatch) -> None:
        frames = batch.frames
        lengths = np.diff(frames.offsets)
        short_noise = np.flatnonzero((batch.role == _NOISE) & (lengths <= 2))
        for position in short_noise.tolist():
            data = frames.data[int(frames.offsets[position]) : int(frames.offsets[position + 1])]
            if set(data) - {0x00, 0xFF}:
                continue
            start, end = int(frames.t_start_ns[position]), int(frames.t_end_ns[position])
            def sender(at: int) -> str | None:
                return _transmitter(int(batch.role[at]), int(batch.slave[at]))

            after = before = None
            if position + 1 < len(batch) and int(frames.t_start_ns[position + 1]) - end <= self._adjacent_ns:
                before = (int(frames.t_start_ns[position + 1]) - end, sender(position + 1))
            previous = (int(frames.t_end_ns[position - 1]), sender(position - 1)) if position else self._previous
            if previous is not None and start - previous[0] <= self._adjacent_ns:
                after = (start - previous[0], previous[1])
            near = min((c for c in (before, after) if c is not None and c[1] is not None), default=None,
                       key=lambda c: c[0])
            if near is not None and near[1] is not None:
                side = "before" if near is before else "after"
                self.glitches[(near[1], side, data.hex())].add(frames.first_index + position)


def diagnose(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    """The findings, errors first, each rule's in order of its evidence."""
    found = [*_silent(statistics, evidence), *_refused(statistics, evidence), *_late(evidence),
             *_crc(statistics, evidence), *_glitches(evidence), *_timing(evidence), *_stalls(statistics, evidence),
             *_busy(statistics), *_broadcasts(statistics)]
    order = {"error": 0, "warning": 1, "info": 2}
    return sorted(found, key=lambda f: order[f.severity])


def _silent(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    found = []
    for health in slave_health(statistics):
        if health.slave == 0 or health.requests < SILENT_REQUESTS:
            continue
        answered = health.responses + sum(health.exceptions.values())
        frames = tuple(evidence.timeouts[health.slave].frames) if health.slave in evidence.timeouts else ()
        evidence_: dict[str, int | float | str] = {"requests": health.requests, "answers": answered,
                                                  "timeouts": health.timeouts}
        causes = ("the slave address set on the device", "its line settings (baud, parity, stop bits)",
                  "the wiring to it (A/B swapped, a loose terminal)", "its power")
        if answered == 0:
            found.append(Finding("silent_slave", "error", f"Slave {health.slave} never answered: {health.requests} "
                                 "requests, no answer.", health.slave, evidence_, frames, causes, ("timeout",)))
        elif health.requests >= RARE_REQUESTS and answered < RARE_SHARE * health.requests:
            found.append(Finding("rare_answers", "warning", f"Slave {health.slave} answered only {answered} of "
                                 f"{health.requests} requests ({answered / health.requests:.0%}).", health.slave,
                                 evidence_, frames, causes, ("timeout",)))
    return found


def _refused(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    answered = Counter[int]()
    for (slave, _), stats in statistics.per_function.items():
        answered[slave] += stats.responses
    found = []
    for (slave, function, code, addresses), seen in sorted(evidence.refused.items(), key=lambda item: str(item[0])):
        count = seen.count
        where = "" if addresses is None else (f" at address {addresses[0]}" if addresses[0] == addresses[1] else
                                              f" at addresses {addresses[0]}..{addresses[1]}")
        also = f", while it answers {answered[slave]} other requests" if answered[slave] else ""
        found.append(Finding(
            "refused_requests", "warning",
            f"Slave {slave} refuses FC {function} ({function_name(function)}){where}: exception {code:02d} "
            f"({exception_name(code)}), {count}×{also}.", slave,
            {"function": function, "exception": code, "count": count,
             **({"first_address": addresses[0], "last_address": addresses[1]} if addresses is not None else {})},
            tuple(seen.frames),
            ("the master asks for what this device lacks: its model, options or firmware",
             "an address off by one (a manual's 1-based or 40001 numbering)", "a profile for another device"),
            ("exception",)))
    return found


def _late(evidence: Evidence) -> list[Finding]:
    found = []
    for slave, pairs in sorted(evidence.late.items()):
        if len(pairs) < LATE_ANSWERS:
            continue
        latency = float(np.median([p[0] for p in pairs])) / 1e6
        wait = float(np.median([p[1] for p in pairs])) / 1e6
        found.append(Finding(
            "late_answers", "warning",
            f"Slave {slave} answers after the master has moved on: its answers come {latency:.1f} ms after the "
            f"request, the master waits {wait:.1f} ms ({len(pairs)} answers too late).", slave,
            {"late_answers": len(pairs), "slave_latency_ms": round(latency, 3), "master_wait_ms": round(wait, 3)},
            tuple(evidence.late_frames[slave].frames),
            ("the master's response timeout is shorter than the slave's answer time: raise it",
             "the slave is busy (a long scan, a parameter being saved)"), ("unexpected", "timeout")))
    return found


def _crc(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    total = statistics.crc_errors
    if not total:
        return []
    share = total / max(statistics.frames - statistics.roles.get("noise", 0), 1)
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
        "crc_errors", severity, f"{total} frame{'s' if total != 1 else ''} with a CRC error ({share:.1%} of the "
        f"frames){said}.", slave if parts and parts[0].endswith(f"slave {slave}") else None,
        {"crc_errors": total, "share": round(share, 5), "in_bursts": in_bursts},
        frames,
        ("the cable: shield, twisted pair, length, stubs", "termination (120 Ω at both ends only) and bias",
         "a noise source near the line or the device (a drive's motor cable)",
         "two transmitters at once (a second master, a device answering for another's address)"),
        ("crc_error",))]


def _glitches(evidence: Evidence) -> list[Finding]:
    found = []
    for (sender, side, data), seen in sorted(evidence.glitches.items()):
        count = seen.count
        if count < GLITCHES:
            continue
        byte = " ".join(f"0x{data[i:i + 2].upper()}" for i in range(0, len(data), 2))
        found.append(Finding(
            "glitch_bytes", "warning",
            f"A stray {byte} {'comes before' if side == 'before' else 'follows'} the frames of "
            f"{'the master' if sender == 'master' else sender} ({count}×).",
            int(sender.split()[1]) if sender.startswith("slave") else None,
            {"transmitter": sender, "side": side, "count": count}, tuple(seen.frames),
            ("the transmitter's driver enable switching too early or too late",
             "missing bias resistors: the idle line floats", "missing or extra termination"), ("noise",)))
    return found


def _named(sender: str) -> str:
    """``The master`` or ``Slave 7``, to begin a sentence."""
    return "The master" if sender == "master" else sender.capitalize()


def _timing(evidence: Evidence) -> list[Finding]:
    found = []
    texts = {"gap_1_5": ("gaps of more than 1.5 characters inside {n} of its {sent} frames",
                         ("a transmitter that pauses inside a frame: a slow or busy device, a USB-RS485 "
                          "converter on the transmitting side", "a gateway that forwards in pieces")),
             "short_idle": ("less than 3.5 characters of silence before {n} of its {sent} frames",
                            ("a device that answers or sends too soon after the last frame",
                             "a master polling faster than the line's t3.5"))}
    for (rule, sender), seen in sorted(evidence.timing.items()):
        count = seen.count
        text, causes = texts[rule]
        found.append(Finding(
            rule, "warning", f"{_named(sender)} sends " + text.format(n=count, sent=evidence.sent[sender]) + ".",
            int(sender.split()[1]) if sender.startswith("slave") else None,
            {"transmitter": sender, "count": count, "frames_sent": evidence.sent[sender]},
            tuple(seen.frames), causes, (rule,)))
    return found


def _stalls(statistics: Statistics, evidence: Evidence) -> list[Finding]:
    found = []
    per_function = statistics.per_function
    for (slave, function), poll in sorted(evidence.polls.items()):
        stats = per_function.get((slave, function))
        usual = stats.poll_period.percentile(50) if stats is not None else None
        if poll.count < STALL_POLLS or usual is None or usual <= 0:
            continue
        limit = max(STALL_TIMES * usual, STALL_NS)
        stopped = (evidence.last_ns or poll.last_ns) - poll.last_ns
        if poll.longest_ns >= limit:
            found.append(Finding(
                "polling_stalls", "warning",
                f"Polling of slave {slave} FC {function} stalled: usually every {usual / 1e6:.0f} ms, once not for "
                f"{poll.longest_ns / 1e9:.1f} s.", slave,
                {"usual_ms": round(usual / 1e6, 3), "longest_s": round(poll.longest_ns / 1e9, 3)},
                (poll.longest_at,) if poll.longest_at >= 0 else (),
                ("the master busy elsewhere (a PLC scan, an HMI page change)", "a communication fault the master "
                 "handles by pausing", "a gateway's queue"), ()))
        elif stopped >= limit:
            found.append(Finding(
                "polling_stops", "warning",
                f"Polling of slave {slave} FC {function} stopped {stopped / 1e9:.1f} s before the capture's end "
                f"(it came every {usual / 1e6:.0f} ms).", slave,
                {"usual_ms": round(usual / 1e6, 3), "stopped_s": round(stopped / 1e9, 3)}, (),
                ("the master stopped asking (a fault it handles, a changed page)", "the master lost the line"), ()))
    return found


def _busy(statistics: Statistics) -> list[Finding]:
    load = statistics.bus_load
    if load is None or load < BUSY_LOAD:
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
