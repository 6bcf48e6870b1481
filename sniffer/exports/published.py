"""Which frames' values the exports plot: only what the wire proves a device holds.

Plots, parameter channels (``/slave/N/params``) and state series are evidence that a drive
ran at a speed or was in a state. So they take a value only from

* a **valid answer** (``response`` with a valid CRC): the values it read, or the value an
  FC 5/6 echo confirms;
* a **write its slave accepted**: the values of a valid FC 15/16/23 request, at the time
  of its valid answer (the answer itself carries only the addresses).

Not from a CRC-damaged frame (its bytes are not what was sent), a request (a write that
was refused with an exception, or never answered, changed nothing), a broadcast (nobody
confirms it), and never a marker such as the Altivar's 16#8000 (``ParamValue.available``
is false: "non-existent or protected", not the number 32768). Those frames stay in the
frame records and the log, marked as what they are.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch
from decoders.message import ROLE_CODE, ParamValue, Role

#: Writes whose answer does not repeat the written values.
WRITES_ANSWERED_WITHOUT_VALUES = (15, 16, 23)
#: Valid write requests kept until their answer: as many as the annotator keeps requests.
KEPT_WRITES = 1024
_RESPONSE, _REQUEST = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.REQUEST]
#: What an export keeps of a write until its answer: its decoding, or the text of its values.
Written = TypeVar("Written")


def plotted(params: Sequence[ParamValue]) -> list[ParamValue]:
    """The params that carry a reading: a raw value that is not a marker."""
    return [param for param in params if param.reading]


class PublishedValues(Generic[Written]):
    """Tells, batch by batch, whose values are published (see the module's rules)."""

    def __init__(self) -> None:
        #: Valid write requests (FC 15, 16, 23) by frame index, awaiting their answer: what
        #: ``select`` was told they wrote.
        self._writes: OrderedDict[int, Written] = OrderedDict()

    def select(
        self, batch: AnnotatedBatch, positions: npt.NDArray[np.int64], written: Callable[[int], Written]
    ) -> tuple[npt.NDArray[np.bool_], list[tuple[int, Written]]]:
        """For the messages at ``positions``: whether each one's own values are published,
        and ``(row, written(request's row))`` for each answer that accepts a write (``row``
        indexes ``positions``; the write's values are published at that answer)."""
        messages = batch.messages
        roles, crc_ok = messages.role[positions], messages.frames.crc_ok[positions]
        answers = (roles == _RESPONSE) & crc_ok
        writes = np.flatnonzero((roles == _REQUEST) & crc_ok & np.isin(messages.function[positions],
                                                                          WRITES_ANSWERED_WITHOUT_VALUES))
        accepted: list[tuple[int, Written]] = []
        first = messages.frames.first_index
        # Writes first: an answer in the same batch comes after its request.
        for row, position in zip(writes.tolist(), positions[writes].tolist(), strict=True):
            self._writes[first + position] = written(row)
            if len(self._writes) > KEPT_WRITES:
                self._writes.popitem(last=False)
        if self._writes:
            requests = messages.request_index[positions]
            open_writes = np.fromiter(self._writes, np.int64, len(self._writes))
            for row in np.flatnonzero(answers & np.isin(requests, open_writes)).tolist():
                accepted.append((row, self._writes.pop(int(requests[row]))))
        return answers, accepted
