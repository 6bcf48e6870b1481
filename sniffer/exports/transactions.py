"""Transactions of the MCAP export: a request and what became of it, as JSON, a batch at a time.

One message per answered request (``answered``, ``exception``, ``crc_error``, at the answer's
start), per request that timed out (``timeout``) and per broadcast (``broadcast``), at the
request's end. A request's bytes are kept until its answer comes, in this batch or a later one.
"""

from __future__ import annotations

from collections import OrderedDict
from itertools import repeat

import numpy as np
import numpy.typing as npt

from decoders.message import NONE, ROLE_CODE, AnnotatedBatch, Role
from sniffer.exports.levels import TIMEOUT
from sniffer.views.rows import Column, Rows, decimal_columns, hex_texts, join_rows, number_texts, or_null

#: Open requests kept for their answers: older ones are forgotten (their answers never came).
KEPT_REQUESTS = 4096
_REQUEST, _BROADCAST, _EXCEPTION = (ROLE_CODE[role] for role in (Role.REQUEST, Role.BROADCAST, Role.EXCEPTION))
OUTCOMES = ["answered", "exception", "crc_error", "timeout", "broadcast"]
_ANSWERED, _EXCEPTION_OUTCOME, _CRC_ERROR, _TIMEOUT_OUTCOME, _BROADCAST_OUTCOME = range(len(OUTCOMES))
_OUTCOME_JSON = [f'"{outcome}"'.encode() for outcome in OUTCOMES]


class TransactionEncoder:
    """``/modbus/transactions`` messages from batches of annotated messages."""

    def __init__(self, reserved: int = 0) -> None:
        """``reserved``: bytes before each message, see :func:`~sniffer.views.rows.join_rows`."""
        self._reserved = reserved
        #: Open requests' hex by frame index, oldest first.
        self._requests: OrderedDict[int, bytes] = OrderedDict()

    def rows(self, batch: AnnotatedBatch, kept: npt.NDArray[np.int64]) -> tuple[Rows, npt.NDArray[np.int64]]:
        """The transactions that the messages at positions ``kept`` close, and their log times."""
        messages, frames = batch.messages, batch.messages.frames
        role, paired = messages.role[kept], messages.request_index[kept]
        indexes = kept + frames.first_index
        hexes = _kept(hex_texts(frames.data, frames.offsets), kept)
        timed_out = (messages.flags[kept] & TIMEOUT) != 0
        opening = np.flatnonzero((role == _REQUEST) & ~timed_out)
        self._requests.update(zip(indexes[opening].tolist(), _kept(hexes, opening), strict=True))
        lonely = ((role == _REQUEST) & timed_out) | (role == _BROADCAST)
        answering = np.flatnonzero((paired != NONE) & (role != _REQUEST) & (role != _BROADCAST))
        request_hex = dict(
            zip(answering.tolist(), map(self._requests.pop, paired[answering].tolist(), repeat(None)), strict=True)
        )
        while len(self._requests) > KEPT_REQUESTS:
            self._requests.popitem(last=False)
        answered = np.zeros(len(kept), np.bool_)
        answered[[row for row, found in request_hex.items() if found is not None]] = True
        emitted = np.flatnonzero(lonely | answered)
        return self._encode(
            batch,
            kept[emitted],
            lonely[emitted],
            [request_hex.get(row) or hexes[row] for row in emitted.tolist()],
            _kept(hexes, emitted),
        )

    def _encode(
        self,
        batch: AnnotatedBatch,
        positions: npt.NDArray[np.int64],
        lonely: npt.NDArray[np.bool_],
        request_hex: list[bytes],
        own_hex: list[bytes],
    ) -> tuple[Rows, npt.NDArray[np.int64]]:
        messages, frames = batch.messages, batch.messages.frames
        role = messages.role[positions]
        indexes = positions + frames.first_index
        outcome = np.where(
            role == _EXCEPTION, _EXCEPTION_OUTCOME, np.where(frames.crc_ok[positions], _ANSWERED, _CRC_ERROR)
        )
        outcome = np.where(lonely, np.where(role == _REQUEST, _TIMEOUT_OUTCOME, _BROADCAST_OUTCOME), outcome)
        latency = np.where(lonely, NONE, messages.latency_ns[positions])
        request = np.where(lonely, indexes, messages.request_index[positions])
        answer = np.where(lonely, NONE, indexes)
        slave, function, code = (
            column[positions] for column in (messages.slave, messages.function, messages.exception_code)
        )
        quote = [b"" if alone else b'"' for alone in lonely.tolist()]
        answer_hex = [b"null" if alone else text for alone, text in zip(lonely.tolist(), own_hex, strict=True)]
        columns: list[Column] = [
            b'{"request_index":', number_texts(request),
            b',"answer_index":', or_null(number_texts(answer), answer, NONE),
            b',"slave":', or_null(number_texts(slave), slave, NONE),
            b',"function":', or_null(number_texts(function), function, NONE),
            b',"outcome":', list(map(_OUTCOME_JSON.__getitem__, outcome.tolist())),
            b',"latency_s":', *decimal_columns(latency, 9, NONE),
            b',"latency_ms":', *decimal_columns(latency, 6, NONE),
            b',"exception_code":', or_null(number_texts(code), code, NONE),
            b',"request":"', request_hex, b'","answer":', quote, answer_hex, quote, b"}",
        ]  # fmt: skip
        times = np.where(lonely, frames.t_end_ns[positions], frames.t_start_ns[positions])
        return join_rows(columns, len(positions), self._reserved), times


def _kept(items: list[bytes], rows: npt.NDArray[np.int64]) -> list[bytes]:
    return items if len(rows) == len(items) else list(map(items.__getitem__, rows.tolist()))
