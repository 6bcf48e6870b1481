"""The sink behind ``rtusniff report``: gathers, in memory that does not grow with the capture,
what the report shows (the statistics, the charts' series, the anomalies, the drive values,
the devices that identified themselves) and where it came from.

``report --each`` gathers every capture on its own (in a process pool) and merges what came
back in the order the files were named (:meth:`ReportCollector.merge`): counts and histograms
add up, the charts' buckets merge exactly (:meth:`decoders.timeline.Timeline.merge`), the
anomalies and state changes keep the first of each kind, labelled with their file.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from decoders.anomalies import anomaly_masks
from decoders.capture import CaptureInfo, TimingQuality
from decoders.compare import Change
from decoders.damage import RetryDiff
from decoders.decoded_batch import AnnotatedBatch
from decoders.distinct import distinct
from decoders.findings import Finding, diagnose
from decoders.line import LineSettings
from decoders.message import ROLE_CODE, DeviceIdentity, MessageBatch, Role
from decoders.stats import Statistics
from decoders.symptoms import Symptoms
from decoders.timeline import Timeline
from sniffer.exports.outputs import sha256_of
from sniffer.report.anomalies import AnomalyLog
from sniffer.report.drive_values import MAX_SERIES, PART_SERIES, DriveValues
from sniffer.sinks import Sink
from sniffer.views.compare_view import Side

_ANSWERS = (ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION])


@dataclass(frozen=True)
class SourceFile:
    path: str
    size: int
    sha256: str


def source_file(path: str) -> SourceFile:
    """A capture file's size and SHA-256 (standard input: neither can be known)."""
    if path == "-" or not os.path.isfile(path):
        return SourceFile(path, 0, "")
    return SourceFile(path, os.path.getsize(path), sha256_of(path))


@dataclass
class Provenance:
    """Where the report came from: enough to check it and to make it again."""

    files: list[SourceFile]
    command: str
    tool_version: str
    profiles: list[str]
    line: str = ""
    timing: str = ""
    channels: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    window: str = ""
    devices: dict[int, DeviceIdentity] = field(default_factory=dict)
    #: Whether the files were read one by one and merged (``--each``): rows name their file.
    merged: bool = False
    #: ``--each``: in how many captures each slave identified itself (each starts knowing none).
    identified_in: Counter[int] = field(default_factory=Counter)


@dataclass(frozen=True)
class Comparison:
    """``--baseline``: an earlier capture (``before``) against this one (``after``), per slave and function."""

    baseline: SourceFile
    before: Side
    after: Side
    changes: list[Change]


class ReportCollector(Sink):
    """Everything the report shows, gathered batch by batch."""

    wants_messages = True
    wants_statistics = True

    def __init__(self, provenance: Provenance, *, part: bool = False) -> None:
        """``part``: a capture of ``report --each``, gathered to be merged (more value series kept)."""
        self.provenance = provenance
        self.timeline = Timeline()
        self.anomalies = AnomalyLog()
        self.values = DriveValues(self.timeline, PART_SERIES if part else MAX_SERIES)
        self.statistics = Statistics()
        self.slaves: set[int] = set()
        self._retries = RetryDiff()
        self._evidence: Symptoms | None = None
        #: What is wrong on the bus (:mod:`decoders.findings`), each with the capture it is in
        #: (``report --each``; empty for one capture), drawn at :meth:`finish`.
        self.findings: list[tuple[str, Finding]] = []

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self.provenance.line = line.format()
        self.provenance.timing = info.timing.value
        self.provenance.channels = info.channels
        self.provenance.notes = info.notes
        self._evidence = Symptoms(int(line.t3_5_ns), info.timing is TimingQuality.EXACT)

    def messages(self, batch: AnnotatedBatch) -> None:
        messages = batch.messages
        if not len(messages):
            return
        masks = anomaly_masks(messages)
        if self._evidence is not None:
            self._evidence.add(messages)
            self._evidence.add_decoded(batch)
        self._over_time(messages, masks)
        self.anomalies.add(batch, masks, self._retries.notes(messages))
        self.values.add(batch)
        for decoding in batch.decoded:  # no frame in columns identifies a device
            if decoding.device is not None:
                self.provenance.devices[decoding.device.slave] = decoding.device

    def _over_time(self, messages: MessageBatch, masks: dict[str, np.ndarray]) -> None:
        frames, timeline = messages.frames, self.timeline
        t_start = frames.t_start_ns
        timeline.add_spans("wire_ns", t_start, frames.t_end_ns)
        for kind, mask in masks.items():
            timeline.add(f"anomaly:{kind}", "sum", t_start[mask])
        answered = np.isin(messages.role, _ANSWERS) & frames.crc_ok & (messages.latency_ns >= 0)
        slaves = messages.slave[answered]
        times, latency_ms = t_start[answered], messages.latency_ns[answered] / 1e6
        for slave in distinct(slaves).tolist():
            self.slaves.add(slave)
            mine = slaves == slave
            timeline.add(f"latency:{slave}:max", "max", times[mine], latency_ms[mine])
            timeline.add(f"latency:{slave}:sum", "sum", times[mine], latency_ms[mine])
            timeline.add(f"latency:{slave}:count", "sum", times[mine])

    def finish(self, statistics: Statistics) -> None:
        self.statistics = statistics
        if self._evidence is not None:
            self.findings = [("", finding) for finding in diagnose(statistics, self._evidence)]

    def portable(self) -> ReportCollector:
        """What a process of the pool sends back (``report --each``): no caches, no state of
        decoding on (the poll periods' last times, the retries awaited)."""
        self.statistics = self.statistics.portable()
        self.anomalies.portable()
        self.values.portable()
        self._retries = RetryDiff()
        self._evidence = None  # its findings are drawn
        return self

    def merge(self, other: ReportCollector) -> None:
        """Add ``other``, the next capture gathered on its own, its rows labelled with its file."""
        capture = other.provenance.files[0].path if len(other.provenance.files) == 1 else ""
        self.statistics.merge(other.statistics)
        self.timeline.merge(other.timeline)
        self.anomalies.merge(other.anomalies, capture)
        self.values.merge(other.values, capture)
        self.slaves |= other.slaves
        if not self.provenance.merged and len(self.provenance.files) == 1:  # the first part: its file named too
            self.findings = [(self.provenance.files[0].path, finding) for _, finding in self.findings]
        self.findings += [(capture, finding) for _, finding in other.findings]
        mine, theirs = self.provenance, other.provenance
        mine.merged = True
        mine.files += theirs.files
        mine.devices.update(theirs.devices)
        mine.identified_in.update(theirs.devices.keys())
        mine.line = _joined(mine.line, theirs.line)
        mine.timing = _joined(mine.timing, theirs.timing)
        mine.channels = tuple(dict.fromkeys([*mine.channels, *theirs.channels]))
        mine.notes = tuple(dict.fromkeys([*mine.notes, *theirs.notes]))


def _joined(known: str, more: str) -> str:
    """``115200 8N1`` and ``19200 8E1``: each text said once, in the order met."""
    parts = [part for part in known.split(", ") if part]
    return ", ".join(parts if more in parts or not more else [*parts, more])
