"""Every anomaly of a capture, by kind, with the frames around the first ones: the report's evidence.

A frame is an anomaly of each kind it shows (:data:`KINDS`); the counts per kind are the ones
``stats`` gives (CRC errors of frames, the flags, exception and noise roles). Memory stays
bounded whatever the capture: the first ``LISTED`` anomalies of each kind are kept as rows, the
first ``WITH_CONTEXT`` of them with ``CONTEXT`` frames before and after (from the neighbouring
batches where they lie across a batch's edge); the rest are counted.
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime

import numpy as np
import numpy.typing as npt

from decoders.anomalies import KINDS
from decoders.decoded_batch import AnnotatedBatch
from decoders.message import ROLE_CODE, Role
from sniffer.views.clock import Clock
from sniffer.views.frame_cells import decoding_summary, frame_cells, frame_notes, summary_cells

_NOISE, _EXCEPTION = ROLE_CODE[Role.NOISE], ROLE_CODE[Role.EXCEPTION]
#: Anomalies kept as rows per kind.
LISTED = 100
#: Of those, the first ones shown with the frames around them.
WITH_CONTEXT = 10
#: Frames before and after an anomaly shown with it.
CONTEXT = 2


@dataclass(frozen=True)
class FrameRow:
    """One frame as the report writes it: every field a text, as the plain table has it."""

    index: int
    t_ns: int
    time: str
    idle_ms: str
    slave: str
    function: str
    role: str
    request: str
    latency_ms: str
    crc: str
    flags: str
    hex: str
    summary: str
    #: The capture file the frame is in, where the report merges several (``report --each``).
    capture: str = ""


@dataclass
class Anomaly:
    kind: str
    row: FrameRow
    before: list[FrameRow] = field(default_factory=list)
    after: list[FrameRow] = field(default_factory=list)
    with_context: bool = False


def utc_text(t_ns: int) -> str:
    """``2023-11-14 22:13:20.052533``: the date and time in UTC, to the microsecond."""
    seconds, nanos = divmod(t_ns, 1_000_000_000)
    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%d %H:%M:%S") + f".{nanos // 1000:06d}"


def frame_rows(batch: AnnotatedBatch, positions: npt.NDArray[np.int64], retries: dict[int, str]) -> list[FrameRow]:
    """The frames at ``positions`` of ``batch`` as rows, with the notes the table adds (CRC
    received and computed, UART errors, a good retry's difference)."""
    if not len(positions):
        return []
    messages = batch.messages
    cells = frame_cells(messages, positions, Clock("utc"), plain=False, styled=False)
    summaries = summary_cells(batch, positions, decoding_summary, frame_notes(messages, positions, retries)).texts
    t_start = messages.frames.t_start_ns[positions].tolist()
    indexes = (positions + messages.frames.first_index).tolist()
    texts = {name: cells[name].texts for name in
             ("idle", "slave", "function", "role", "request", "latency", "crc", "flags", "hex")}
    return [FrameRow(indexes[k], t_start[k], utc_text(t_start[k]), texts["idle"][k], texts["slave"][k],
                     texts["function"][k], texts["role"][k], texts["request"][k], texts["latency"][k],
                     texts["crc"][k], texts["flags"][k], texts["hex"][k], summaries[k])
            for k in range(len(positions))]


class AnomalyLog:
    """Counts every anomaly and keeps the first of each kind (see the module docstring)."""

    def __init__(self, listed: int = LISTED, with_context: int = WITH_CONTEXT, context: int = CONTEXT) -> None:
        self.listed, self.with_context, self.context = listed, with_context, context
        self.counts: Counter[str] = Counter()
        self.kept: dict[str, list[Anomaly]] = {kind: [] for kind in KINDS}
        #: The last frames of the batches so far, for the frames before an anomaly at a batch's start.
        self._tail: deque[FrameRow] = deque(maxlen=context)
        #: Anomalies still short of frames after them.
        self._waiting: list[Anomaly] = []

    def add(self, batch: AnnotatedBatch, masks: dict[str, npt.NDArray[np.bool_]], retries: dict[int, str]) -> None:
        size = len(batch.messages)
        if not size:
            return
        chosen: dict[str, list[int]] = {}
        for kind, mask in masks.items():
            positions = np.flatnonzero(mask)
            self.counts[kind] += len(positions)
            room = self.listed - len(self.kept[kind])
            if room > 0 and len(positions):
                chosen[kind] = positions[:room].tolist()
        wanted = set(range(min(self.context, size))) | set(range(max(size - self.context, 0), size))
        for kind, picked in chosen.items():
            wanted.update(picked)
            contexts = max(self.with_context - len(self.kept[kind]), 0)
            for position in picked[:contexts]:
                wanted.update(range(max(position - self.context, 0), min(position + self.context + 1, size)))
        order = np.array(sorted(wanted), np.int64)
        rows = dict(zip(order.tolist(), frame_rows(batch, order, retries), strict=True))
        self._fill_waiting(rows, size)
        for kind, picked in chosen.items():
            for position in picked:
                self._keep(kind, position, rows, size)
        for position in range(max(size - self.context, 0), size):
            self._tail.append(rows[position])

    def _keep(self, kind: str, position: int, rows: dict[int, FrameRow], size: int) -> None:
        anomaly = Anomaly(kind, rows[position])
        kept = self.kept[kind]
        if len(kept) < self.with_context:
            anomaly.with_context = True
            earlier = [rows[p] for p in range(max(position - self.context, 0), position)]
            tail, needed = list(self._tail), self.context - len(earlier)
            anomaly.before = (tail[max(len(tail) - needed, 0):] if needed else []) + earlier
            anomaly.after = [rows[p] for p in range(position + 1, min(position + self.context + 1, size))]
            if len(anomaly.after) < self.context:
                self._waiting.append(anomaly)
        kept.append(anomaly)

    def _fill_waiting(self, rows: dict[int, FrameRow], size: int) -> None:
        still = []
        for anomaly in self._waiting:
            missing = self.context - len(anomaly.after)
            anomaly.after += [rows[p] for p in range(min(missing, size))]
            if len(anomaly.after) < self.context:
                still.append(anomaly)
        self._waiting = still

    def portable(self) -> AnomalyLog:
        """This log as another process sends it back: the anomalies still short of frames after
        them stay so (the next frames are in another capture)."""
        self._waiting = []
        return self

    def merge(self, other: AnomalyLog, capture: str) -> None:
        """Add the counts and kept anomalies of ``other`` (a capture read on its own), its rows
        labelled with ``capture``: still the first of each kind, in the order merged."""
        self.counts.update(other.counts)
        for kind, theirs in other.kept.items():
            kept = self.kept.setdefault(kind, [])
            for anomaly in theirs[: max(self.listed - len(kept), 0)]:
                contexts = sum(a.with_context for a in kept)
                with_context = anomaly.with_context and contexts < self.with_context
                kept.append(Anomaly(kind, _labelled(anomaly.row, capture),
                                    [_labelled(row, capture) for row in anomaly.before] if with_context else [],
                                    [_labelled(row, capture) for row in anomaly.after] if with_context else [],
                                    with_context))


def _labelled(row: FrameRow, capture: str) -> FrameRow:
    return replace(row, capture=capture)
