"""The value rows of a capture (long form): every value a slave reported or was written.

The rule, shared by ``rtusniff values`` (:mod:`sniffer.views.values`) and the Parquet ``values``
table (:mod:`sniffer.exports.parquet_export`): a row per frame that carried values, ``reported``
(an answer) or ``written`` (a write request or broadcast), with a ``valid`` per value:

* a reported value is valid when its answer's CRC holds and the value is a reading, not a
  marker (the Altivar's 16#8000 "non-existent or protected");
* a written value is valid when its slave accepted the write: a valid answer to a valid request
  (an exception, no answer, a broadcast or a damaged frame: not valid). Its rows wait for the
  answer, and carry the request's time and index.

:class:`ValueRows` finds the rows; a subclass says what becomes of each (:meth:`ValueRows.output`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from decoders.decoded_batch import AnnotatedBatch, Params
from decoders.frame import FrameFlag
from decoders.message import NONE, ROLE_CODE, ParamValue, Role
from decoders.stats import Statistics
from sniffer.sinks import Sink

#: Write requests kept until their answer (as many as the annotator keeps requests).
KEPT_WRITES = 1024
_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION]
#: The functions whose requests carry written values.
WRITES = frozenset({5, 6, 15, 16, 23})
#: The kinds of value rows, by code (the Parquet ``values`` table's ``kind``).
VALUE_KINDS = ("reported", "written")
REPORTED, WRITTEN = 0, 1
_TIMEOUT = int(FrameFlag.TIMEOUT)
#: :attr:`ValueRows.emitting` after the last frame: past every frame index.
AT_THE_END = 1 << 62


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
class ValueRow:
    t_ns: int
    index: int
    slave: int
    kind: str
    params: tuple[ParamValue, ...]
    request_index: int | None
    #: The frame's params, all of them, as the decoded form shares them between frames alike:
    #: what a subclass may cache by (:attr:`params` are those chosen).
    found: Params
    valid: list[bool] = field(default_factory=list)
    #: The frame's function (its data table: registers, coils or inputs).
    function: int = 0


class ValueRows(Sink):
    """Finds the value rows of annotated batches, in capture order (written rows once answered)."""

    wants_messages = True

    def __init__(self, choice: ValueChoice | None = None) -> None:
        self._choice = choice or ValueChoice()
        #: Valid write requests awaiting their answer, by frame index.
        self._writes: OrderedDict[int, ValueRow] = OrderedDict()
        #: The last value of each (slave, address, kind), for ``changes``.
        self._last: dict[tuple[int, int, str], object] = {}
        #: Value rows given to :meth:`output`.
        self.shown = 0
        #: The frame index of the message being read (an output's row is found there; a written
        #: row waits for its answer's); :data:`AT_THE_END` once the capture has ended.
        self.emitting = 0

    def output(self, row: ValueRow) -> None:
        """A row, its params chosen and each one's validity set."""
        raise NotImplementedError

    def messages(self, batch: AnnotatedBatch) -> None:
        self.rows_at(batch, batch.positions(), batch.message_params())

    def rows_at(self, batch: AnnotatedBatch, positions: list[int], each_params: list[Params]) -> None:
        """The rows of the messages at ``positions`` (of the batch's kept positions, in order;
        ``each_params``: the params of each message, by position)."""
        messages, frames = batch.messages, batch.messages.frames
        first = frames.first_index
        self._first_frame(frames.t_start_ns)
        # The columns of these positions alone: a batch hands most of its frames to the rows in
        # bulk and a few here (listing its whole columns would cost every batch).
        at = np.array(positions, np.int64)
        role, slave, function, crc, flags, request, t_start = (column[at].tolist() for column in (
            messages.role, messages.slave, messages.function, frames.crc_ok, messages.flags, messages.request_index,
            frames.t_start_ns))
        for place, position in enumerate(positions):
            self.emitting = first + position
            params = each_params[position]
            kind = role[place]
            if kind in (_RESPONSE, _EXCEPTION) and request[place] != NONE:
                self._answered(request[place], valid=kind == _RESPONSE and bool(crc[place]))
            if slave[place] == NONE or not params:
                continue
            row = ValueRow(t_start[place], first + position, slave[place], "", params,
                           None if request[place] == NONE else request[place], found=params, function=function[place])
            if kind == _RESPONSE:
                row.kind = "reported"
                self._emit(row, crc_ok=bool(crc[place]))
            elif kind in (_REQUEST, _BROADCAST) and function[place] in WRITES:
                self._written(row, kind=kind, crc_ok=bool(crc[place]), timed_out=bool(flags[place] & _TIMEOUT))

    def _written(self, row: ValueRow, *, kind: int, crc_ok: bool, timed_out: bool) -> None:
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

    def _first_frame(self, t_start_ns: object) -> None:
        """Each batch's start times, before its rows (``--time relative`` counts from the first)."""

    def _emit(self, row: ValueRow, *, crc_ok: bool) -> None:
        params = [p for p in row.params if p.raw is not None and self._choice.wants(row.slave, p)]
        if self._choice.changes:
            params = [p for p in params if self._changed(row, p)]
        if not params:
            return
        row.params = tuple(params)
        row.valid = [crc_ok and (p.available or row.kind == "written") for p in params]
        self.shown += len(params)
        self.output(row)

    def _changed(self, row: ValueRow, param: ParamValue) -> bool:
        key = (row.slave, param.address, row.kind)
        if key in self._last and self._last[key] == param.value:
            return False
        self._last[key] = param.value
        return True

    def finish(self, statistics: Statistics) -> None:
        self.emitting = AT_THE_END
        for row in list(self._writes.values()):
            self._emit(row, crc_ok=False)  # no answer before the capture ended
        self._writes.clear()
