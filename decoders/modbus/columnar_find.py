"""Which frames of a batch stay in columns (:mod:`decoders.modbus.columnar`), found with numpy.

Which functions, and in which shape, is the codec registry's to say
(:data:`~decoders.modbus.codecs.BULK_SHAPES`: FC 1 to 4 read, 5 and 6 write one value, 15 and 16
write many, 23 reads and writes). The rules; every frame also is ``eligible`` (the annotator's to
say: Modbus, of a slave whose profile adds nothing or names plainly,
:mod:`decoders.profiles.columns`), has a good CRC and the shape its function has in
:func:`~decoders.modbus.codecs.parse_pdu`, with counts Modbus allows:

* a read request (a read's function, role request, 8 bytes);
* a read's answer (role response): a byte count that counts the rest of the frame, even for
  registers; the first message of the capture to name its request (the one the annotator reads
  against it), within :data:`~decoders.modbus.columnar.KEPT_REQUESTS` frames of it; the request
  a read of the same function kept in columns, or kept by the annotator from before the batch;
* a write (a single or multiple write's function; role request; not timed out), kept only together with its answer in
  the same batch (the matcher delivers a request with its outcome), which is kept when it is
  the write's echo (a single write) or its confirmation (a multiple one: 8 bytes), the first message to
  name the write;
* a read/write request (FC 23; role request; not timed out; a byte count for the registers it writes,
  counts Modbus allows), kept only together with its answer in the same batch, the first message
  to name it: a register answer (its byte count even and counting the rest of the frame), which
  reports registers from the request's first read one.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from decoders.modbus.codecs import BIT_VALUES, BULK_MULTIPLE, BULK_READ, BULK_READ_WRITE, BULK_SHAPES, BULK_SINGLE
from decoders.modbus.codes import MAX_READ_WRITE_QUANTITY
from decoders.modbus.columnar import KEPT_REQUESTS, MOST, ColumnarFrames
from decoders.modbus.columnar_text import READ, READ_ANSWER, READ_WRITE, WRITE, WRITE_ANSWER, words_at

_REQUEST, _RESPONSE = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.RESPONSE]
_TIMEOUT = int(FrameFlag.TIMEOUT)
_SHORT = 8  # bytes of a read request, a single write and its echo, a multiple write's answer
_MULTIPLE_HEAD = 9  # bytes of a multiple write but its values
_SHORTEST_ANSWER = 6  # a read's answer with one byte of data
_READ_WRITE_HEAD = 13  # bytes of an FC 23 request but its values

#: Where a frame's data (values or bits) starts, by its kind and whether its function is a single
#: write (its value, or its echo's): -1, none (a read request, a multiple write's answer).
_DATA_AT = np.full((5, 2), -1, np.int64)
_DATA_AT[READ_ANSWER] = 3
_DATA_AT[WRITE] = (7, 4)
_DATA_AT[WRITE_ANSWER, 1] = 4
_DATA_AT[READ_WRITE] = (11, 4)

#: The function, first address and count of a read request kept before the batch, by its frame
#: index (``None``: none such).
EarlierRead = Callable[[int], "tuple[int, int, int] | None"]


class _Columns:
    """A batch's columns as the rules read them."""

    def __init__(self, batch: MessageBatch, eligible: npt.NDArray[np.bool_]) -> None:
        frames = batch.frames
        self.batch, self.first, self.size = batch, frames.first_index, len(batch)
        self.starts, self.lengths = frames.offsets[:-1], np.diff(frames.offsets)
        self.raw = np.frombuffer(frames.data, np.uint8)  # widened where read (:meth:`byte`, :meth:`word`)
        self.function = batch.function.astype(np.int64)
        #: Each frame's function's shape in bulk (:data:`~decoders.modbus.codecs.BULK_SHAPES`).
        self.shape = BULK_SHAPES[self.function]
        self.good = eligible & frames.crc_ok
        self._of_role = {role: self.good & (batch.role == role) for role in (_REQUEST, _RESPONSE)}
        self.request = batch.request_index
        #: Each frame's kind, first address and count, as the rules find them (-1: not kept).
        self.kind = np.full(self.size, -1, np.int64)
        self.address = np.full(self.size, -1, np.int64)
        self.count = np.full(self.size, -1, np.int64)
        #: An FC 23 request's read span (-1 and 0: none).
        self.read_address = np.full(self.size, -1, np.int64)
        self.read_count = np.zeros(self.size, np.int64)

    def byte(self, positions: npt.NDArray[np.int64], offset: int) -> npt.NDArray[np.int64]:
        """The byte at ``offset`` of each frame at ``positions``."""
        byte: npt.NDArray[np.int64] = self.raw[self.starts[positions] + offset].astype(np.int64)
        return byte

    def word(self, positions: npt.NDArray[np.int64], offset: int) -> npt.NDArray[np.int64]:
        """The big-endian word at ``offset`` of each frame at ``positions``."""
        return words_at(self.raw, self.starts[positions] + offset)

    def of(self, role: int, *shapes: int) -> npt.NDArray[np.bool_]:
        """Good frames of ``role`` (a request or an answer) whose function has one of ``shapes``."""
        table = np.zeros(BULK_SHAPES.max() + 1, np.bool_)
        table[list(shapes)] = True
        found: npt.NDArray[np.bool_] = self._of_role[role] & table[self.shape]
        return found

    def single(self, positions: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
        """Whether the function of each frame at ``positions`` is a single write."""
        single: npt.NDArray[np.bool_] = self.shape[positions] == BULK_SINGLE
        return single


def find_columnar(batch: MessageBatch, eligible: npt.NDArray[np.bool_], earlier: EarlierRead) -> ColumnarFrames:
    """The frames of ``batch`` kept in columns (see the module docstring); ``eligible``: Modbus
    frames of slaves whose profile adds nothing; ``earlier``: the reads kept before the batch."""
    columns = _Columns(batch, eligible)
    size, first, function = columns.size, columns.first, columns.function
    kind, address, count = columns.kind, columns.address, columns.count
    reads = np.flatnonzero(columns.of(_REQUEST, BULK_READ) & (columns.lengths == _SHORT))
    asked = columns.word(reads, 4)
    reads = reads[(asked >= 1) & (asked <= MOST[function[reads]])]
    kind[reads], address[reads], count[reads] = READ, columns.word(reads, 2), columns.word(reads, 4)
    writes = _shaped_writes(columns)
    kind[writes], address[writes] = WRITE, columns.word(writes, 2)
    count[writes] = np.where(columns.single(writes), 1, columns.word(writes, 4))
    _read_writes(columns)

    answers = _first_answers(columns)
    earlier_requests = _read_answers(columns, answers, earlier)
    answered = _write_answers(columns, answers)
    read_writes = answers[(kind[answers] == READ_ANSWER) & (columns.shape[answers] == BULK_READ_WRITE)]
    answered[columns.request[read_writes] - first] = True
    kind[((kind == WRITE) | (kind == READ_WRITE)) & ~answered] = -1
    answers = answers[kind[answers] >= 0]

    positions = np.flatnonzero(kind >= 0)
    named = columns.request[answers] - first
    consumed = np.zeros(size, np.bool_)
    consumed[named[named >= 0]] = True
    answer_of = np.full(size, -1, np.int64)
    answer_of[named[named >= 0]] = answers[named >= 0]
    starts = columns.starts[positions]
    kinds, functions = kind[positions], function[positions]
    byte_count = np.where(kinds == READ_ANSWER, columns.raw[starts + 2], 0).astype(np.int64)
    data_at = _DATA_AT[kinds, columns.single(positions).astype(np.intp)]
    data = np.where(data_at >= 0, starts + data_at, -1)
    return ColumnarFrames(
        positions=positions, function=functions, kind=kinds, address=address[positions], count=count[positions],
        read_address=columns.read_address[positions], read_count=columns.read_count[positions],
        data=data, byte_count=byte_count,
        request=np.where((kinds == READ_ANSWER) | (kinds == WRITE_ANSWER), columns.request[positions], NONE),
        answer=answer_of[positions], kept_requests=reads[~consumed[reads]], earlier_requests=earlier_requests)


def _shaped_writes(columns: _Columns) -> npt.NDArray[np.int64]:
    """Write requests of the shape ``parse_pdu`` reads, not timed out."""
    function, lengths = columns.function, columns.lengths
    writes = np.flatnonzero(columns.of(_REQUEST, BULK_SINGLE, BULK_MULTIPLE) & ((columns.batch.flags & _TIMEOUT) == 0))
    single = columns.single(writes)
    shaped = single & (lengths[writes] == _SHORT)
    many = np.flatnonzero(~single & (lengths[writes] >= _MULTIPLE_HEAD))  # its count and byte count inside the frame
    frames = writes[many]
    count = columns.word(frames, 4)
    byte_count = columns.byte(frames, 6)
    needed = np.where(BIT_VALUES[function[frames]], (count + 7) // 8, 2 * count)
    shaped[many] = (lengths[frames] == _MULTIPLE_HEAD + byte_count) & (byte_count == needed) & (count >= 1) & (
        count <= MOST[function[frames]])
    kept: npt.NDArray[np.int64] = writes[shaped]  # in order, as ``writes`` (not union1d, which sorts them)
    return kept


def _read_writes(columns: _Columns) -> None:
    """Marks the FC 23 requests of the shape ``parse_pdu`` reads, not timed out, with counts
    Modbus allows and a byte count for the registers written (the written span first: its
    values lie in the frame, and its params come first)."""
    lengths = columns.lengths
    asks = np.flatnonzero(columns.of(_REQUEST, BULK_READ_WRITE) & ((columns.batch.flags & _TIMEOUT) == 0)
                          & (lengths >= _READ_WRITE_HEAD))
    read_count, write_count = columns.word(asks, 4), columns.word(asks, 8)
    byte_count = columns.byte(asks, 10)
    read_most, write_most = MAX_READ_WRITE_QUANTITY
    asks = asks[(lengths[asks] == _READ_WRITE_HEAD + byte_count) & (byte_count == 2 * write_count)
                & (read_count >= 1) & (read_count <= read_most) & (write_count >= 1) & (write_count <= write_most)]
    columns.kind[asks], columns.address[asks], columns.count[asks] = READ_WRITE, columns.word(asks, 6), \
        columns.word(asks, 8)
    columns.read_address[asks], columns.read_count[asks] = columns.word(asks, 2), columns.word(asks, 4)


def _first_answers(columns: _Columns) -> npt.NDArray[np.int64]:
    """Good answers to reads and writes, each the first message to name its request, within
    :data:`KEPT_REQUESTS` frames of it."""
    answers = np.flatnonzero(columns.of(_RESPONSE, BULK_READ, BULK_SINGLE, BULK_MULTIPLE, BULK_READ_WRITE)
                             & (columns.request != NONE))
    naming = np.flatnonzero(columns.request != NONE)
    named = columns.request[naming]
    if len(named) and (named[1:] >= named[:-1]).all():  # in order, as a bus answers: each run's first
        firsts = np.flatnonzero(np.concatenate(([True], named[1:] != named[:-1])))
    else:
        firsts = np.unique(named, return_index=True)[1]
    first_naming = np.zeros(columns.size, np.bool_)
    first_naming[naming[firsts]] = True
    request = columns.request[answers]
    is_first = first_naming[answers]
    distance = columns.first + answers - request
    kept: npt.NDArray[np.int64] = answers[is_first & (distance > 0) & (distance <= KEPT_REQUESTS)]
    return kept


def _read_answers(columns: _Columns, answers: npt.NDArray[np.int64], earlier: EarlierRead) -> list[int]:
    """Marks the answers to reads whose byte count fits and whose request is a read of their
    function kept in columns or kept before the batch (their address and count: the request's),
    or an FC 23 request kept in columns (the first register it reads); the frame indexes of the
    reads from before the batch."""
    function, first = columns.function, columns.first
    kind, address, count = columns.kind, columns.address, columns.count
    shape = columns.shape
    reads = answers[((shape[answers] == BULK_READ) | (shape[answers] == BULK_READ_WRITE))
                    & (columns.lengths[answers] >= _SHORTEST_ANSWER)]
    byte_count = columns.byte(reads, 2)
    fits = (byte_count == columns.lengths[reads] - 5) & (byte_count > 0) & ~(
        ~BIT_VALUES[function[reads]] & (byte_count % 2 == 1))
    reads = reads[fits]
    request = columns.request[reads]
    inside = request >= first
    here, local = reads[inside], request[inside] - first
    read_write = shape[here] == BULK_READ_WRITE
    fits = (kind[local] == np.where(read_write, READ_WRITE, READ)) & (function[local] == function[here])
    here, local, read_write = here[fits], local[fits], read_write[fits]
    kind[here], address[here] = READ_ANSWER, np.where(read_write, columns.read_address[local], address[local])
    registers = ~BIT_VALUES[function[here]]
    answer_bytes = columns.byte(here, 2)
    count[here] = np.where(registers, answer_bytes // 2, np.minimum(count[local], 8 * answer_bytes))
    earlier_requests = []
    for position, index in zip(reads[~inside].tolist(), request[~inside].tolist(), strict=True):
        read = earlier(index)
        if read is not None and read[0] == function[position] and 1 <= read[2] <= MOST[read[0]]:
            words = int(columns.raw[columns.starts[position] + 2])
            kind[position], address[position] = READ_ANSWER, read[1]
            count[position] = min(read[2], 8 * words) if BIT_VALUES[read[0]] else words // 2
            earlier_requests.append(index)
    return earlier_requests


def _write_answers(columns: _Columns, answers: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """Marks the answers to writes kept in columns (the echo or the confirmation, 8 bytes, of
    the batch's write of their function); which writes were so answered."""
    function, first, kind = columns.function, columns.first, columns.kind
    shape = columns.shape[answers]
    echoes = answers[((shape == BULK_SINGLE) | (shape == BULK_MULTIPLE)) & (columns.lengths[answers] == _SHORT)]
    local = columns.request[echoes] - first
    inside = local >= 0
    echoes, local = echoes[inside], local[inside]
    confirmed = columns.word(echoes, 4)
    single = columns.single(echoes)
    fits = (kind[local] == WRITE) & (function[local] == function[echoes]) & (
        single | ((confirmed >= 1) & (confirmed <= MOST[function[echoes]])))
    echoes, local, single = echoes[fits], local[fits], single[fits]
    kind[echoes], columns.address[echoes] = WRITE_ANSWER, columns.word(echoes, 2)
    columns.count[echoes] = np.where(single, 1, columns.word(echoes, 4))
    answered = np.zeros(columns.size, np.bool_)
    answered[local] = True
    return answered
