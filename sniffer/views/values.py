"""``rtusniff values``: every value a slave reported or was written, over time.

A row per value (long form): the frame's time and index, the slave, whether the value was
``reported`` (in an answer: the registers read, an FC 5/6 echo) or ``written`` (in a write
request or broadcast), the register's address, the profile's code, name and unit, the raw word,
the value as the device means it, the request the row belongs to, and ``valid``:

* a reported value is valid when its answer's CRC holds and the value is a reading, not a
  marker (the Altivar's 16#8000 "non-existent or protected");
* a written value is valid when its slave accepted the write: a valid answer to a valid request
  (an exception, no answer, a broadcast or a damaged frame: not valid). Its rows wait for the
  answer, and carry the request's time and index.

``--changes`` keeps a row only when its value differs from the last one of the same slave,
address and kind; ``--wide`` writes one row per frame with a column per parameter instead (the
rows are held until the end, to know every column).
"""

from __future__ import annotations

import csv
import json
from collections import OrderedDict
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, TextIO

import numpy as np

from decoders.capture import CaptureInfo
from decoders.frame import FrameFlag
from decoders.line import LineSettings
from decoders.message import NONE, ROLE_CODE, AnnotatedBatch, Decoding, ParamValue, Role
from decoders.stats import Statistics
from sniffer.sinks import Sink

LONG_COLUMNS = ("time", "t_ns", "index", "slave", "kind", "address", "code", "name", "raw", "value", "unit",
                "request_index", "valid")
WIDE_FIXED = ("time", "t_ns", "index", "slave", "kind")
#: Write requests kept until their answer (as many as the annotator keeps requests).
KEPT_WRITES = 1024
_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION]
_WRITES = frozenset({5, 6, 15, 16, 23})
_TIMEOUT = int(FrameFlag.TIMEOUT)


@dataclass(frozen=True)
class ValueChoice:
    """Which values to write: slaves (empty: all), parameters by code or address (empty: all)."""

    slaves: frozenset[int] = frozenset()
    params: frozenset[str] = frozenset()
    changes: bool = False

    def wants(self, slave: int, param: ParamValue) -> bool:
        if self.slaves and slave not in self.slaves:
            return False
        return not self.params or str(param.address) in self.params or (param.code or "") in self.params


@dataclass
class _Row:
    t_ns: int
    index: int
    slave: int
    kind: str
    params: tuple[ParamValue, ...]
    request_index: int | None
    valid: list[bool] = field(default_factory=list)


class ValuesView(Sink):
    """Writes the rows (see the module docstring) as CSV or JSON Lines."""

    wants_messages = True

    def __init__(self, out: TextIO, choice: ValueChoice, *, as_json: bool, wide: bool, time_mode: str) -> None:
        self._out, self._choice, self._json, self._wide, self._mode = out, choice, as_json, wide, time_mode
        #: ``--time relative`` counts from the first frame read.
        self._origin_ns: int | None = None
        self._csv = csv.writer(out, lineterminator="\n")
        #: Valid write requests awaiting their answer, by frame index.
        self._writes: OrderedDict[int, _Row] = OrderedDict()
        #: The last value of each (slave, address, kind), for ``--changes``.
        self._last: dict[tuple[int, int, str], object] = {}
        self._held: list[tuple[_Row, int]] = []
        #: Value rows written (or held, when wide).
        self.shown = 0

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        if not self._json and not self._wide:
            self._csv.writerow(LONG_COLUMNS)

    def messages(self, batch: AnnotatedBatch) -> None:
        messages, frames = batch.messages, batch.messages.frames
        first = frames.first_index
        if self._origin_ns is None and len(frames):
            self._origin_ns = int(frames.t_start_ns[0])
        role, slave, function = messages.role.tolist(), messages.slave.tolist(), messages.function.tolist()
        crc, flags, request = frames.crc_ok.tolist(), messages.flags.tolist(), messages.request_index.tolist()
        t_start = frames.t_start_ns.tolist()
        for position in batch.positions():
            decoding: Decoding = batch.decodings[position]
            kind = role[position]
            if kind in (_RESPONSE, _EXCEPTION) and request[position] != NONE:
                self._answered(request[position], valid=kind == _RESPONSE and bool(crc[position]))
            if slave[position] == NONE or not decoding.params:
                continue
            row = _Row(t_start[position], first + position, slave[position], "", decoding.params,
                       None if request[position] == NONE else request[position])
            if kind == _RESPONSE:
                row.kind = "reported"
                self._emit(row, crc_ok=bool(crc[position]))
            elif kind in (_REQUEST, _BROADCAST) and function[position] in _WRITES:
                self._written(row, kind=kind, crc_ok=bool(crc[position]), timed_out=bool(flags[position] & _TIMEOUT))

    def _written(self, row: _Row, *, kind: int, crc_ok: bool, timed_out: bool) -> None:
        row.kind, row.request_index = "written", row.index
        if kind == _BROADCAST or not crc_ok or timed_out:
            self._emit(row, crc_ok=False)  # nobody accepted it
            return
        self._writes[row.index] = row
        if len(self._writes) > KEPT_WRITES:
            self._emit(self._writes.popitem(last=False)[1], crc_ok=False)

    def _answered(self, request_index: int, *, valid: bool) -> None:
        row = self._writes.pop(request_index, None)
        if row is not None:
            self._emit(row, crc_ok=valid)

    def _emit(self, row: _Row, *, crc_ok: bool) -> None:
        params = [p for p in row.params if p.raw is not None and self._choice.wants(row.slave, p)]
        if self._choice.changes:
            params = [p for p in params if self._changed(row, p)]
        if not params:
            return
        row.params = tuple(params)
        row.valid = [crc_ok and (p.available or row.kind == "written") for p in params]
        self.shown += len(params)
        if self._wide:
            self._held.append((row, len(self._held)))
        elif self._json:
            self._out.write("".join(json.dumps(record, ensure_ascii=False) + "\n" for record in self._records(row)))
        else:
            self._csv.writerows([[_cell(record[name]) for name in LONG_COLUMNS] for record in self._records(row)])

    def _changed(self, row: _Row, param: ParamValue) -> bool:
        key = (row.slave, param.address, row.kind)
        if key in self._last and self._last[key] == param.value:
            return False
        self._last[key] = param.value
        return True

    def _records(self, row: _Row) -> list[dict[str, Any]]:
        time = self._time(row.t_ns)
        return [{"time": time, "t_ns": row.t_ns, "index": row.index, "slave": row.slave, "kind": row.kind,
                 "address": p.address, "code": p.code, "name": p.name, "raw": p.raw, "value": p.value,
                 "unit": p.unit, "request_index": row.request_index, "valid": valid}
                for p, valid in zip(row.params, row.valid, strict=True)]

    def finish(self, statistics: Statistics) -> None:
        for row in list(self._writes.values()):
            self._emit(row, crc_ok=False)  # no answer before the capture ended
        self._writes.clear()
        if self._wide:
            self._write_wide()
        self._out.flush()

    def _write_wide(self) -> None:
        """A row per frame, a column per parameter (``SLAVE:CODE``, or ``SLAVE:ADDRESS``)."""
        held = sorted(self._held, key=lambda item: (item[0].t_ns, item[1]))
        names: dict[str, None] = {}
        for row, _ in held:
            for param in row.params:
                names[_column(row.slave, param)] = None
        order = sorted(names, key=_column_order)
        if self._json:
            for row, _ in held:
                record = {**{name: value for name, value in zip(WIDE_FIXED, self._fixed(row), strict=True)},
                          **{_column(row.slave, p): p.value for p in row.params}}
                self._out.write(json.dumps(record, ensure_ascii=False) + "\n")
            return
        self._csv.writerow([*WIDE_FIXED, *order])
        for row, _ in held:
            values = {_column(row.slave, p): p.value for p in row.params}
            self._csv.writerow([*map(_cell, self._fixed(row)), *(_cell(values.get(name)) for name in order)])

    def _fixed(self, row: _Row) -> list[object]:
        return [self._time(row.t_ns), row.t_ns, row.index, row.slave, row.kind]

    def _time(self, t_ns: int) -> str:
        """ISO 8601 with microseconds (``Z`` for UTC, the offset for local time), or seconds since
        the first frame read (``relative``): what a spreadsheet or pandas reads as a time."""
        if self._mode == "relative":
            return f"{(t_ns - (self._origin_ns or t_ns)) // 1000 / 1e6:.6f}"
        seconds, nanos = divmod(t_ns, 1_000_000_000)
        moment = datetime.fromtimestamp(seconds, UTC).replace(microsecond=nanos // 1000)
        if self._mode == "local":
            return moment.astimezone().isoformat(timespec="microseconds")
        return moment.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _column(slave: int, param: ParamValue) -> str:
    return f"{slave}:{param.code if param.code is not None else param.address}"


def _column_order(name: str) -> tuple[int, str]:
    slave, _, what = name.partition(":")
    return int(slave), what


def _cell(value: object) -> object:
    """A CSV cell: empty for none, ``true``/``false`` for booleans (as JSON writes them)."""
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    return value
