"""Drive values over time and state changes, for the report's charts, in bounded memory.

Only what a device profile names (a code such as RFRD or ETA) is taken, from frames whose CRC
holds: values a slave reported (its answers) and values a master sent (its write requests).

* A number goes to a series per slave, code and direction on the report's :class:`Timeline`:
  per bucket its minimum, maximum and last value. The first ``MAX_SERIES`` series are kept;
  more are counted (``rtusniff values`` has them all).
* A text (a state word the profile spells out, ETA "operation enabled, forward") is a state:
  each change of a slave's code is kept, the first ``MAX_CHANGES`` of them.

Separate captures of one bus (``report --each``) merge in time order (:meth:`DriveValues.merge`):
a capture's first state of a code is a change only where it differs from the last state the
captures before it left.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from decoders.decoded_batch import AnnotatedBatch, Params
from decoders.memo import KeptByIdentity
from decoders.message import ROLE_CODE, Role
from decoders.timeline import Merge, Timeline
from sniffer.encoding.value_rows import WRITES

MAX_SERIES = 48
#: Series a capture of ``report --each`` keeps: the merge keeps the first ``MAX_SERIES`` of all
#: captures, which may be any of a capture's own (a capture's 60th may be the plant's 3rd).
PART_SERIES = 1024
MAX_CHANGES = 500
#: Frames' params remembered with what they hold (equal frames share them).
CACHED = 4096
_RESPONSE = ROLE_CODE[Role.RESPONSE]
_SENT = (ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST])
_MERGES: tuple[Merge, ...] = ("min", "max", "last")


@dataclass(frozen=True)
class ValueSeries:
    """What one series plots: slave, code, name, unit, and ``reported`` or ``sent``."""

    slave: int
    code: str
    name: str
    unit: str
    kind: str

    @property
    def key(self) -> str:
        return f"value:{self.slave}:{self.code}:{self.kind}"


@dataclass(frozen=True)
class StateChange:
    t_ns: int
    index: int
    slave: int
    code: str
    name: str
    before: str | None
    after: str
    #: The capture file the frame is in, where the report merges several (``report --each``).
    capture: str = ""


_Numbers = list[tuple[str, str, str, float]]
_Texts = list[tuple[str, str, str]]


class DriveValues:
    """Feeds named values to a timeline and keeps state changes (see the module docstring)."""

    def __init__(self, timeline: Timeline, max_series: int = MAX_SERIES) -> None:
        self._timeline = timeline
        self._max_series = max_series
        self.series: dict[tuple[int, str, str], ValueSeries] = {}
        self._left_out: set[tuple[int, str, str]] = set()
        self.changes: list[StateChange] = []
        self.changes_total = 0
        self._states: dict[tuple[int, str], str] = {}
        #: The first state seen of each slave's code (what a capture before this one is compared with).
        self._firsts: dict[tuple[int, str], str] = {}
        #: What each frame's params name, by the tuple's identity (equal frames share it).
        self._named: KeptByIdentity[Params, tuple[_Numbers, _Texts]] = KeptByIdentity(_named, CACHED)

    @property
    def series_left_out(self) -> int:
        """Series seen beyond the ones kept."""
        return len(self._left_out)

    def add(self, batch: AnnotatedBatch) -> None:
        messages = batch.messages
        crc_ok = messages.frames.crc_ok
        answers = (messages.role == _RESPONSE) & crc_ok
        writes = np.isin(messages.role, _SENT) & np.isin(messages.function, sorted(WRITES)) & crc_ok
        positions = np.flatnonzero(answers | writes).tolist()
        if not positions:
            return
        slaves, t_start = messages.slave.tolist(), messages.frames.t_start_ns.tolist()
        sent = writes.tolist()
        times: dict[tuple[int, str, str], list[int]] = {}
        values: dict[tuple[int, str, str], list[float]] = {}
        each_params = batch.message_params()
        for position in positions:
            params = each_params[position]
            if not params:
                continue
            numbers, texts = self._named.of(params)
            slave, kind = slaves[position], "sent" if sent[position] else "reported"
            for code, name, unit, number in numbers:
                key = (slave, code, kind)
                if self._series(key, name, unit):
                    times.setdefault(key, []).append(t_start[position])
                    values.setdefault(key, []).append(number)
            for code, name, text in texts:
                self._state((t_start[position], messages.frames.first_index + position, slave), code, name, text)
        for key, at in times.items():
            name = self.series[key].key
            t_ns, readings = np.array(at, np.int64), np.array(values[key])
            for merge in _MERGES:
                self._timeline.add(f"{name}:{merge}", merge, t_ns, readings)

    def _series(self, key: tuple[int, str, str], name: str, unit: str) -> bool:
        if key in self.series:
            return True
        if len(self.series) >= self._max_series:
            self._left_out.add(key)
            return False
        self.series[key] = ValueSeries(key[0], key[1], name, unit, key[2])
        return True

    def _state(self, seen: tuple[int, int, int], code: str, name: str, text: str) -> None:
        """A state text ``seen`` (time, frame index, slave) in a frame."""
        t_ns, index, slave = seen
        before = self._states.get((slave, code))
        if before == text:
            return
        if before is None:
            self._firsts[(slave, code)] = text
        self._states[(slave, code)] = text
        self.changes_total += 1
        if len(self.changes) < MAX_CHANGES:
            self.changes.append(StateChange(t_ns, index, slave, code, name, before, text))

    def portable(self) -> DriveValues:
        """These values without the cache of named params: what another process sends back."""
        self._named.kept = {}
        return self

    def merge(self, other: DriveValues, capture: str) -> None:
        """Add the series and state changes of ``other``, a later capture of the same bus read
        on its own. The timeline has merged ``other``'s buckets already (:meth:`Timeline.merge`):
        the series left out here leave it, as they would never have entered one timeline."""
        for series_key, series in other.series.items():
            if series_key not in self.series and len(self.series) < self._max_series:
                self.series[series_key] = series
        seen = other.series.keys() | other._left_out
        self._left_out |= {series_key for series_key in seen if series_key not in self.series}
        for series_key in other.series.keys() - self.series.keys():
            for merge in _MERGES:
                self._timeline.series.pop(f"{other.series[series_key].key}:{merge}", None)
        for change in other.changes:
            key = (change.slave, change.code)
            before = change.before if change.before is not None else self._states.get(key)
            if before != change.after and len(self.changes) < MAX_CHANGES:
                self.changes.append(replace(change, before=before, capture=capture))
        # A first state equal to the last one before it is no change (kept or not).
        same = sum(self._states.get(key) == text for key, text in other._firsts.items())
        self.changes_total += other.changes_total - same
        for state_key, text in other._firsts.items():
            self._firsts.setdefault(state_key, text)
        self._states.update(other._states)


def _named(params: Params) -> tuple[_Numbers, _Texts]:
    """The profile-named numbers and texts of ``params``."""
    numbers: _Numbers = []
    texts: _Texts = []
    for param in params:
        if param.code is None or not param.available or param.value is None:
            continue
        if isinstance(param.value, str):
            texts.append((param.code, param.name or param.code, param.value))
        elif not isinstance(param.value, bool):
            numbers.append((param.code, param.name or param.code, param.unit or "", float(param.value)))
    return numbers, texts
