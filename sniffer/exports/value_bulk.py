"""Which value rows of a batch can be found in bulk, and which need the rule frame by frame.

The rule (:mod:`sniffer.encoding.value_rows`) walks the frames in order because a write's rows
wait for its answer, and at most ``KEPT_WRITES`` wait: one more pushes the oldest out. In a batch
where that cannot happen (the writes waiting before it, and the most of its own that wait at once,
each until its first answer, fit), the rows of frames whose params a profile named need no walk:

- an answer that answers no write that may still wait: its values, reported, found at it, valid
  where its CRC holds (and each value is a reading);
- a write its slave did not accept (a broadcast, a damaged frame, a timeout): its values,
  written, found at it, none valid;
- a write answered in the batch: its values, written, found at its first answer, valid where
  that answer is a response with a good CRC.

The rest goes frame by frame: writes and answers of values no profile names (runs), writes
not answered in the batch, answers to writes that wait. ``tests/property/test_value_blocks.py``
holds the rows found this way to the rule's.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameFlag
from decoders.message import NONE, ROLE_CODE, Role
from decoders.modbus.columnar import one_of
from decoders.modbus.param_runs import LazyParams
from sniffer.encoding.value_rows import KEPT_WRITES, WRITES

#: The kinds of value rows, by code (the ``values`` table's ``kind``).
VALUE_KINDS = ("reported", "written")
REPORTED, WRITTEN = 0, 1
_REQUEST, _BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]
_RESPONSE, _EXCEPTION = ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION]
_WRITE_FUNCTIONS = sorted(WRITES)
Indexes = npt.NDArray[np.int64]


@dataclass(frozen=True)
class BulkRows:
    """Rows of one kind: ``carrier``: the place in the positions given of the frame whose values
    they are; ``positions``: that frame's position in the batch; ``at``: the batch position where
    each is found; ``valid``: whether its slave took it (values that are markers aside)."""

    kind: int
    carrier: Indexes
    positions: Indexes
    at: Indexes
    valid: npt.NDArray[np.bool_]


@dataclass(frozen=True)
class BulkFinding:
    """The rows found in bulk, and the places in the positions given of the frames left to the rule."""

    written: BulkRows
    reported: BulkRows
    one_by_one: Indexes


def bulk_rows(batch: AnnotatedBatch, positions: list[int], pending: Collection[int]) -> BulkFinding | None:
    """The rows of the frames at ``positions`` (decoded one by one) found in bulk (``pending``: frame indexes of the
    writes waiting for their answer); ``None`` where a write might be pushed out."""
    messages, first = batch.messages, batch.messages.frames.first_index
    kept = np.array(positions, np.int64)
    role, slave, request = messages.role[kept], messages.slave[kept], messages.request_index[kept]
    crc = messages.frames.crc_ok[kept]
    writes = one_of(role, (_REQUEST, _BROADCAST)) & one_of(messages.function[kept], _WRITE_FUNCTIONS) & (
        slave != NONE)
    may_wait = writes & (role == _REQUEST) & crc & ((messages.flags[kept] & FrameFlag.TIMEOUT) == 0)
    answering = one_of(role, (_RESPONSE, _EXCEPTION)) & (request != NONE)
    first_answer = _first_answers(kept + first, request, answering)
    if len(pending) + _most_waiting(may_wait, first_answer) > KEPT_WRITES:
        return None
    decodings = batch.decoded_at(positions)
    named = np.fromiter([not isinstance(decoding, LazyParams) for decoding in decodings], np.bool_, len(kept))
    refused = writes & named & ~may_wait
    paired = writes & named & may_wait & (first_answer >= 0)
    waiting = may_wait & ~paired
    to_waiting = answering & np.isin(request, np.concatenate([np.fromiter(pending, np.int64, len(pending)),
                                                              kept[waiting] + first]))
    answers = (role == _RESPONSE) & (slave != NONE)
    reported = np.flatnonzero(answers & named & ~to_waiting)
    written = np.flatnonzero(refused | paired)
    written_at = np.where(paired[written], first_answer[written], written)
    return BulkFinding(
        BulkRows(WRITTEN, written, kept[written], kept[written_at],
                 paired[written] & (role[written_at] == _RESPONSE) & crc[written_at]),
        BulkRows(REPORTED, reported, kept[reported], kept[reported], crc[reported]),
        np.flatnonzero(waiting | (writes & ~named) | to_waiting | (answers & ~named)),
    )


def _first_answers(indexes: Indexes, request: Indexes, answering: npt.NDArray[np.bool_]) -> Indexes:
    """For each frame (``indexes``: theirs), the place of the first answer to it (``-1``: none)."""
    answer_places = np.flatnonzero(answering)
    asked, first = np.unique(request[answer_places], return_index=True)
    if not len(asked):
        return np.full(len(indexes), -1, np.int64)
    at = np.minimum(np.searchsorted(asked, indexes), len(asked) - 1)
    places: Indexes = np.where(asked[at] == indexes, answer_places[first[at]], -1)
    return places


def _most_waiting(may_wait: npt.NDArray[np.bool_], first_answer: Indexes) -> int:
    """The most writes of the batch that wait at once: each from its frame to its first answer
    (to the batch's end without one; those waiting before the batch are counted by the caller)."""
    if not may_wait.any():
        return 0
    change = np.zeros(len(may_wait), np.int64)
    change[may_wait] = 1
    answers = first_answer[may_wait]
    np.subtract.at(change, answers[answers >= 0], 1)
    return int(np.cumsum(change).max())
