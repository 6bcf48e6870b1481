"""Transactions of the MCAP export: a request and what became of it, as JSON, a batch at a time.

One message per answered request (``answered``, ``exception``, ``crc_error``, at the answer's
start), per request that timed out (``timeout``) and per broadcast (``broadcast``), at the
request's end. A request's bytes are kept until its answer comes, in this batch or a later one.
Built from framed and paired messages alone, no decodings: with a decoding process
(:mod:`sniffer.decoding_process`) they are built there, next to the framing.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import numpy.typing as npt

from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from sniffer.encoding.blocks import Block
from sniffer.encoding.rows import (
    Integers,
    Pieces,
    Rows,
    hex_texts,
    join_rows,
)
from sniffer.exports.levels import TIMEOUT

#: Open requests kept for their answers: older ones are forgotten (their answers never came).
KEPT_REQUESTS = 4096
_REQUEST, _BROADCAST, _EXCEPTION = (ROLE_CODE[role] for role in (Role.REQUEST, Role.BROADCAST, Role.EXCEPTION))
OUTCOMES = ["answered", "exception", "crc_error", "timeout", "broadcast"]
_ANSWERED, _EXCEPTION_OUTCOME, _CRC_ERROR, _TIMEOUT_OUTCOME, _BROADCAST_OUTCOME = range(len(OUTCOMES))


class TransactionEncoder:
    """``/modbus/transactions`` messages from batches of annotated messages."""

    def __init__(self, reserved: int = 0) -> None:
        """``reserved``: bytes before each message, see :func:`~sniffer.encoding.rows.join_rows`."""
        self._reserved = reserved
        #: Open requests' hex by frame index, oldest first.
        self._requests: OrderedDict[int, bytes] = OrderedDict()

    def rows(self, messages: MessageBatch, kept: npt.NDArray[np.int64]) -> tuple[Rows, npt.NDArray[np.int64]]:
        """The transactions that the messages at positions ``kept`` close, and their log times."""
        positions, lonely, request_hex, answer_hex = self._closed(messages, kept, spelt=True)
        assert request_hex is not None and answer_hex is not None
        return self._encode(messages, positions, lonely, request_hex, answer_hex)

    def columns(self, messages: MessageBatch, kept: npt.NDArray[np.int64]) -> dict[str, npt.NDArray[np.int64]]:
        """The same transactions as columns (``NONE`` where empty): ``t_ns``, ``request_index``,
        ``answer_index``, ``slave``, ``function``, ``outcome`` (an index into :data:`OUTCOMES`),
        ``exception_code``, ``latency_ns``."""
        positions, lonely, _, _ = self._closed(messages, kept, spelt=False)
        return {**_outcomes(messages, positions, lonely),
                "slave": messages.slave[positions].astype(np.int64),
                "function": messages.function[positions].astype(np.int64),
                "exception_code": messages.exception_code[positions].astype(np.int64)}

    def _closed(self, messages: MessageBatch, kept: npt.NDArray[np.int64], *, spelt: bool) -> tuple[
            npt.NDArray[np.int64], npt.NDArray[np.bool_], Pieces | None, Pieces | None]:
        """The positions of the messages that close a transaction, whether each is a lonely
        request or broadcast, and (``spelt``) the request's and the answer's hex: the columns need
        none, and spelling every frame's was a tenth of the decoding process's work for Parquet.

        An answer takes its request from this batch (found by numpy) or from the requests
        kept open from earlier batches; the first answer to a request takes it, later ones
        find nothing (as they would have after an answer popped it)."""
        frames = messages.frames
        role, paired = messages.role[kept], messages.request_index[kept]
        hexes = _kept(hex_texts(frames.data, frames.offsets, quoted=True), kept) if spelt else None
        timed_out = (messages.flags[kept] & TIMEOUT) != 0
        opening = np.flatnonzero((role == _REQUEST) & ~timed_out)
        opening_index = (kept + frames.first_index)[opening]
        lonely = ((role == _REQUEST) & timed_out) | (role == _BROADCAST)
        answering = np.flatnonzero((paired != NONE) & (role != _REQUEST) & (role != _BROADCAST))
        answering = answering[np.sort(np.unique(paired[answering], return_index=True)[1])]
        targets = paired[answering]
        at = np.minimum(np.searchsorted(opening_index, targets), max(len(opening) - 1, 0))
        here = (opening_index[at] == targets) if len(opening) else np.zeros(len(targets), np.bool_)
        #: Each row's request: its own row (lonely requests and broadcasts) or its request's row.
        request_rows = np.arange(len(kept))
        request_rows[answering[here]] = opening[at[here]]
        answered = np.zeros(len(kept), np.bool_)
        answered[answering[here]] = True
        earlier = {row: self._requests.pop(target, None) for row, target in
                   zip(answering[~here].tolist(), targets[~here].tolist(), strict=True)}  # fmt: skip
        answered[[row for row, found in earlier.items() if found is not None]] = True
        unanswered = np.ones(len(opening), np.bool_)
        unanswered[at[here]] = False
        opened = opening_index[unanswered].tolist()
        # Unspelt, a request kept open is kept as b"": that it is open is all the columns ask.
        self._requests.update(zip(opened, [b""] * len(opened) if hexes is None else _kept(hexes, opening[unanswered]),
                                  strict=True))
        while len(self._requests) > KEPT_REQUESTS:
            self._requests.popitem(last=False)
        emitted = np.flatnonzero(lonely | answered)
        if hexes is None:
            return kept[emitted], lonely[emitted], None, None
        request_hex = hexes.take(request_rows[emitted])
        for place in np.flatnonzero(np.isin(emitted, list(earlier))).tolist():
            found = earlier[int(emitted[place])]
            assert found is not None
            request_hex[place], request_hex.sizes[place] = found, len(found)
        return kept[emitted], lonely[emitted], request_hex, _kept(hexes, emitted)

    def _encode(
        self,
        messages: MessageBatch,
        positions: npt.NDArray[np.int64],
        lonely: npt.NDArray[np.bool_],
        request_hex: Pieces,
        answer_hex: Pieces,
    ) -> tuple[Rows, npt.NDArray[np.int64]]:
        columns = _outcomes(messages, positions, lonely)
        outcome, latency = columns["outcome"], columns["latency_ns"]
        request, answer = columns["request_index"], columns["answer_index"]
        answer_hex.fill(np.flatnonzero(lonely), b"null")
        facts = _facts(messages.slave[positions], messages.function[positions], outcome,
                       messages.exception_code[positions])  # fmt: skip
        block = (
            Block(len(positions))
            .text(b'{"request_index":').integers(request)
            .text(b',"answer_index":').integers(answer, NONE)
            .text(b",").choice(*facts)
            .text(b',"latency_s":').decimals(latency, 9, NONE)
            .text(b',"latency_ms":').decimals(latency, 6, NONE)
            .text(b',"request":')
            .pieces()
        )  # fmt: skip
        rows = join_rows([block, request_hex, b',"answer":', answer_hex, b"}"], len(positions), self._reserved)
        return rows, columns["t_ns"]


def _outcomes(messages: MessageBatch, positions: npt.NDArray[np.int64],
              lonely: npt.NDArray[np.bool_]) -> dict[str, npt.NDArray[np.int64]]:
    """Per closed transaction: its time (the answer's start; a lonely request's end), request and
    answer index, outcome and latency."""
    frames = messages.frames
    role = messages.role[positions]
    indexes = positions + frames.first_index
    outcome = np.where(
        role == _EXCEPTION, _EXCEPTION_OUTCOME, np.where(frames.crc_ok[positions], _ANSWERED, _CRC_ERROR)
    )
    outcome = np.where(lonely, np.where(role == _REQUEST, _TIMEOUT_OUTCOME, _BROADCAST_OUTCOME), outcome)
    return {"t_ns": np.where(lonely, frames.t_end_ns[positions], frames.t_start_ns[positions]),
            "request_index": np.where(lonely, indexes, messages.request_index[positions]),
            "answer_index": np.where(lonely, NONE, indexes), "outcome": outcome,
            "latency_ns": np.where(lonely, NONE, messages.latency_ns[positions])}


def _facts(slave: Integers, function: Integers, outcome: Integers, code: Integers) -> tuple[Integers, list[bytes]]:
    """``"slave":…,"function":…,"outcome":…,"exception_code":…`` per transaction, as the
    combination each row has and the combinations' texts: a bus has few, each spelt once per
    batch from its first row (one packed key per row: ``np.unique`` over rows sorts them)."""
    keys = (((slave.astype(np.int64) + 1) * 257 + function + 1) * 257 + code + 1) * len(OUTCOMES) + outcome
    _, firsts, rows = np.unique(keys, return_index=True, return_inverse=True)
    spelt = (column[firsts].tolist() for column in (slave, function, outcome, code))
    texts = [
        b'"slave":%s,"function":%s,"outcome":"%s","exception_code":%s'
        % (_number_or_null(slave), _number_or_null(function), OUTCOMES[outcome].encode(), _number_or_null(code))
        for slave, function, outcome, code in zip(*spelt, strict=True)
    ]
    return rows, texts


def _number_or_null(value: int) -> bytes:
    return b"null" if value == NONE else b"%d" % value


def _kept(items: Pieces, rows: npt.NDArray[np.int64]) -> Pieces:
    """The pieces at ``rows`` (sorted, distinct: all of them when as many)."""
    return items if len(rows) == len(items) else items.take(rows)
