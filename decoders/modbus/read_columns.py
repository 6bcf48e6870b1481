"""Register and coil reads and their answers kept in columns: no PDU, decoding or param object.

A polling master's reads and its slaves' answers are most frames of a bus; where the values
change, each is new to the annotator's memo and costs a PDU, a decoding and a param per value,
which an output that writes columns (the Parquet dataset) only takes apart again. Here the
batch's plain reads are found with numpy and kept as columns (:class:`ReadColumns`): where each
frame is, its function, the first address it names and how many values, where an answer's data
lies. :meth:`ReadColumns.summaries` writes their summary lines and :meth:`ReadColumns.values`
their values as the PDUs and :mod:`decoders.modbus.param_runs` do; the tests hold both, and the
annotator's state after each batch, to the plain path (:meth:`Annotator.annotate_batch`).

A frame is kept in columns when it is

* a read request: role request, CRC good, FC 1 to 4, 8 bytes, a count Modbus allows; or
* an answer to one: role response, CRC good, the request's function, a byte count that counts
  the rest of the frame (more than none; even for registers), the first message of the capture
  to name that request (the one the annotator would read against it), within
  :data:`KEPT_REQUESTS` frames of it;

and its slave's profile adds nothing to it (``eligible``, the annotator's to say: a named
drive's values go through its profile). A request whose answer is not in the batch's columns is
still kept by the annotator for its answer (``kept_requests``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from decoders.modbus.codes import MAX_QUANTITY
from decoders.modbus.quick import SHOWN_WORDS

#: Requests are read against by answers that come within this many frames of them.
KEPT_REQUESTS = 1024
_TABLES = {1: "coils", 2: "inputs", 3: "HR", 4: "IR"}
_REQUEST, _RESPONSE = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.RESPONSE]
_MOST = np.zeros(5, np.int64)
for _function in range(1, 5):
    _MOST[_function] = MAX_QUANTITY[_function]
#: Each byte's bits as summary text, least significant first (as ``_bit_string`` writes them).
_BYTE_TEXT = ["".join(str(byte >> bit & 1) for bit in range(8)) for byte in range(256)]
_SHOWN_BIT_BYTES = 4  # a summary writes 32 bits, then "…"
_REQUEST_BYTES = 8

#: The function, first address and count of a read request kept before the batch, by its frame
#: index (``None``: none such).
EarlierRead = Callable[[int], "tuple[int, int, int] | None"]


@dataclass(frozen=True)
class ReadColumns:
    """The frames of a batch kept in columns, by position (ascending), one entry each.

    ``address`` and ``count``: the first register or coil a frame names and how many (an answer:
    its request's first, and the values it carries of those asked); ``data``: where an answer's
    data bytes start in the batch's data (``NONE`` for a request); ``request``: an answer's
    request (frame index). ``kept_requests``: positions of requests no answer here read.
    ``earlier_requests``: frame indexes of requests from before the batch these answers read."""

    positions: npt.NDArray[np.int64]
    function: npt.NDArray[np.int64]
    is_answer: npt.NDArray[np.bool_]
    address: npt.NDArray[np.int64]
    count: npt.NDArray[np.int64]
    data: npt.NDArray[np.int64]
    byte_count: npt.NDArray[np.int64]
    request: npt.NDArray[np.int64]
    kept_requests: npt.NDArray[np.int64]
    earlier_requests: list[int]

    def __len__(self) -> int:
        return len(self.positions)

    def kept(self) -> list[tuple[int, int, int, int]]:
        """Position, function, first address and count of each of ``kept_requests``."""
        at = np.searchsorted(self.positions, self.kept_requests)
        return list(zip(self.kept_requests.tolist(), self.function[at].tolist(), self.address[at].tolist(),
                        self.count[at].tolist(), strict=True))

    def summaries(self, data: bytes) -> list[str]:
        """Each frame's summary line, as its PDU's ``summary()`` writes it."""
        texts = []
        for function, answer, address, count, start, size in zip(
                self.function.tolist(), self.is_answer.tolist(), self.address.tolist(), self.count.tolist(),
                self.data.tolist(), self.byte_count.tolist(), strict=True):
            table = _TABLES[function]
            if not answer:
                span = f"{address}" if count == 1 else f"{address}..{address + count - 1}"
                texts.append(f"read {table} {span} ({count})")
            elif function >= 3:
                words = size // 2
                shown = data[start : start + 2 * min(words, SHOWN_WORDS)].hex(" ", 2).upper()
                more = f" … (+{words - SHOWN_WORDS})" if words > SHOWN_WORDS else ""
                texts.append(f"{table} = {shown}{more} ({words} registers)")
            else:
                shown = "".join(map(_BYTE_TEXT.__getitem__, data[start : start + min(size, _SHOWN_BIT_BYTES)]))
                texts.append(f"{table} = {shown}{'…' if size > _SHOWN_BIT_BYTES else ''} ({size} bytes)")
        return texts

    def values(self, data: bytes) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """The answers' values, answer after answer: the position of the answer each came in,
        its address and its raw value (a register's word; a coil or input as 0 or 1)."""
        answers = np.flatnonzero(self.is_answer)
        counts = self.count[answers]
        total = int(counts.sum())
        within = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        start = np.repeat(self.data[answers], counts)
        bits = np.repeat(self.function[answers] <= 2, counts)
        raw = np.frombuffer(data, np.uint8).astype(np.int64)
        at = np.where(bits, start + (within >> 3), start + 2 * within)
        words = (raw[at] << 8) | raw[np.minimum(at + 1, len(raw) - 1)]
        value = np.where(bits, (raw[at] >> (within & 7)) & 1, words)
        return (np.repeat(self.positions[answers], counts), np.repeat(self.address[answers], counts) + within,
                value)


def find_reads(batch: MessageBatch, eligible: npt.NDArray[np.bool_], earlier: EarlierRead) -> ReadColumns:
    """The frames of ``batch`` kept in columns (see the module docstring); ``eligible``: Modbus
    frames of slaves whose profile adds nothing; ``earlier``: the reads kept before the batch."""
    frames = batch.frames
    first, size = frames.first_index, len(batch)
    starts, lengths = frames.offsets[:-1], np.diff(frames.offsets)
    raw = np.frombuffer(frames.data, np.uint8).astype(np.int64)
    function = batch.function.astype(np.int64)
    reads = eligible & frames.crc_ok & (function >= 1) & (function <= 4)
    requests = np.flatnonzero(reads & (batch.role == _REQUEST) & (lengths == _REQUEST_BYTES))
    at = starts[requests]
    asked_address = (raw[at + 2] << 8) | raw[at + 3]
    asked_count = (raw[at + 4] << 8) | raw[at + 5]
    allowed = (asked_count >= 1) & (asked_count <= _MOST[function[requests]])
    requests = requests[allowed]
    # The first address and count asked, by position, of requests and of the answers read
    # against them (-1: no frame kept in columns there).
    address_at, count_at = np.full(size, -1, np.int64), np.full(size, -1, np.int64)
    address_at[requests], count_at[requests] = asked_address[allowed], asked_count[allowed]
    answers = _shaped_answers(batch, reads, raw)
    earlier_requests = _read_against(batch, answers, function=function, address_at=address_at, count_at=count_at,
                                     earlier=earlier)
    answers = answers[address_at[answers] >= 0]
    consumed = np.zeros(size, np.bool_)
    answered = batch.request_index[answers] - first
    consumed[answered[answered >= 0]] = True

    positions = np.union1d(requests, answers)
    is_answer = np.zeros(size, np.bool_)
    is_answer[answers] = True
    answer = is_answer[positions]
    function = function[positions]
    byte_count = np.where(answer, raw[starts[positions] + 2], 0)
    carried = np.where(function >= 3, byte_count // 2, np.minimum(count_at[positions], 8 * byte_count))
    return ReadColumns(
        positions=positions, function=function, is_answer=answer, address=address_at[positions],
        count=np.where(answer, carried, count_at[positions]), data=np.where(answer, starts[positions] + 3, NONE),
        byte_count=byte_count, request=np.where(answer, batch.request_index[positions], NONE),
        kept_requests=requests[~consumed[requests]], earlier_requests=earlier_requests)


def _read_against(batch: MessageBatch, answers: npt.NDArray[np.int64], *, function: npt.NDArray[np.int64],
                  address_at: npt.NDArray[np.int64], count_at: npt.NDArray[np.int64],
                  earlier: EarlierRead) -> list[int]:
    """Sets each answer's address and count to its request's, where that is a read of its
    function kept in columns or kept before the batch; the frame indexes of the latter."""
    first = batch.frames.first_index
    request = batch.request_index[answers]
    inside = request >= first
    here, local = answers[inside], request[inside] - first
    fits = (count_at[local] >= 0) & (function[local] == function[here])
    address_at[here[fits]], count_at[here[fits]] = address_at[local[fits]], count_at[local[fits]]
    earlier_requests = []
    for position, index in zip(answers[~inside].tolist(), request[~inside].tolist(), strict=True):
        read = earlier(index)
        if read is not None and read[0] == function[position] and 1 <= read[2] <= _MOST[read[0]]:
            address_at[position], count_at[position] = read[1], read[2]
            earlier_requests.append(index)
    return earlier_requests


def _shaped_answers(batch: MessageBatch, reads: npt.NDArray[np.bool_], raw: npt.NDArray[np.int64]) -> npt.NDArray[
        np.int64]:
    """Positions of read answers whose byte count fits, each the first message to name its
    request, within :data:`KEPT_REQUESTS` frames of it."""
    first, starts, lengths = batch.frames.first_index, batch.frames.offsets[:-1], np.diff(batch.frames.offsets)
    answers = np.flatnonzero(reads & (batch.role == _RESPONSE) & (lengths >= 6) & (batch.request_index != NONE))
    byte_count = raw[starts[answers] + 2]
    registers = batch.function[answers] >= 3
    fits = (byte_count == lengths[answers] - 5) & (byte_count > 0) & ~(registers & (byte_count % 2 == 1))
    answers = answers[fits]
    naming = np.flatnonzero(batch.request_index != NONE)
    named, first_naming = np.unique(batch.request_index[naming], return_index=True)
    request = batch.request_index[answers]
    is_first = naming[first_naming[np.searchsorted(named, request)]] == answers
    distance = first + answers - request
    kept: npt.NDArray[np.int64] = answers[is_first & (distance > 0) & (distance <= KEPT_REQUESTS)]
    return kept
