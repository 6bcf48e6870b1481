"""Findings: what is wrong on the bus, in words an engineer acts on.

:class:`~decoders.symptoms.Symptoms` follows a capture batch by batch and keeps, in bounded
memory, what the rules below weigh. :func:`diagnose` turns it and the capture's :class:`~decoders.stats.Statistics` into
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

from decoders.health import slave_health
from decoders.message import NONE
from decoders.modbus.codes import exception_name, function_name
from decoders.stats import Statistics
from decoders.symptoms import FIRST, WRITES, Seen, Symptoms, Word

SILENT_REQUESTS = 3
RARE_REQUESTS = 10
RARE_SHARE = 0.5
LATE_ANSWERS = 2
CRC_WARNING_SHARE = 0.01
CRC_WARNING_COUNT = 3
CONCENTRATED = 0.8
BURST_NS = 1_000_000_000
GLITCHES = 2
STALL_POLLS = 10
STALL_TIMES = 10
STALL_NS = 1_000_000_000
BUSY_LOAD = 0.7
TWO_MASTERS_OVERLAPS = 5
TWO_MASTERS_SPREAD = 0.5


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


def diagnose(statistics: Statistics, evidence: Symptoms) -> list[Finding]:
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


def _silent(statistics: Statistics, evidence: Symptoms) -> list[Finding]:
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


def _refused(statistics: Statistics, evidence: Symptoms) -> list[Finding]:
    """By function, exception and addresses, the slaves that refuse them."""
    groups: defaultdict[tuple[int, int, tuple[int, int] | None], list[tuple[int, Seen]]] = defaultdict(list)
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
               if function in WRITES else ())),
            ("exception",)))
    return found


def _faults(evidence: Symptoms) -> list[Finding]:
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


def _late(evidence: Symptoms) -> list[Finding]:
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


def _two_masters(evidence: Symptoms) -> list[Finding]:
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


def _read_back(evidence: Symptoms) -> list[Finding]:
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


def _said(word: Word) -> str:
    return f"16#{word.raw:04X}" + (f" ({word.said})" if word.said else "")


def _crc(statistics: Statistics, evidence: Symptoms) -> list[Finding]:
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


def _glitches(evidence: Symptoms) -> list[Finding]:
    """By side and bytes, the transmitters with at least ``GLITCHES`` of them."""
    groups: defaultdict[tuple[str, str], list[tuple[str, Seen]]] = defaultdict(list)
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


def _timing(evidence: Symptoms) -> list[Finding]:
    """By flag, the transmitters whose frames show it."""
    texts = {"gap_1_5": ("gaps of more than 1.5 characters inside {n} of {their} {sent} frames",
                         ("a transmitter that pauses inside a frame: a slow or busy device, a USB-RS485 "
                          "converter on the transmitting side", "a gateway that forwards in pieces")),
             "short_idle": ("less than 3.5 characters of silence before {n} of {their} {sent} frames",
                            ("a device that answers or sends too soon after the last frame",
                             "a master polling faster than the line's t3.5"))}
    groups: defaultdict[str, list[tuple[str, Seen]]] = defaultdict(list)
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


def _stalls(statistics: Statistics, evidence: Symptoms) -> list[Finding]:
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
                 if slave == 0 and function in WRITES)
    if not writes:
        return []
    return [Finding("unconfirmed_broadcasts", "info", f"{writes} broadcast write{'s' if writes != 1 else ''}: no "
                    "slave answers a broadcast, so nothing on the bus confirms them.", 0, {"broadcast_writes": writes},
                    (), ("read the values back from each slave to know they took them",), ())]
