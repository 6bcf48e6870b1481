"""What each message says: its decoded PDU, the registers or coils it names, one summary line.

Responses are read against their request (a register response carries values, its
request the addresses), so the annotator keeps the decoded requests that still
await an answer.

A bus repeats itself: a master polls the same registers over and over and drives
answer with the same values. What a frame says depends only on its bytes, role and
protocol, what its request asked (:func:`answer_context`) and what the profiles know at
that moment, so :meth:`Annotator.annotate_batch` decodes each such combination once and hands the same
:class:`Decoding` to every repeat. The profiles' ``version`` is part of the key: a
frame that taught them something (a scanner table, an identification) is decoded
again, never answered from before. A frame new to the memo but for its values (the same read
answered with new values) is decoded from its values and what an earlier frame of its shape
said (:mod:`decoders.modbus.value_shapes`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch
from decoders.distinct import distinct
from decoders.frame import USS
from decoders.memo import Memo
from decoders.message import IN_COLUMNS, NONE, ROLE_CODE, ROLE_ORDER, Decoding, Message, MessageBatch, Role
from decoders.modbus.codes import function_name
from decoders.modbus.columnar import KEPT_REQUESTS, ColumnarFrames
from decoders.modbus.columnar_find import find_columnar
from decoders.modbus.param_runs import LazyParams
from decoders.modbus.pdu import (
    ExceptionPdu,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    WriteCoilsRequest,
    WriteRegistersRequest,
)
from decoders.modbus.pdu_parse import parse_as
from decoders.modbus.quick import QuickRead, register_reads
from decoders.modbus.value_shapes import ValueShapes
from decoders.profiles.apply import FrameFacts, ProfileApplier
from decoders.profiles.book import ProfileBook
from decoders.profiles.column_names import named
from decoders.profiles.columns import frame_profiles, learning_slaves, plain_codes, unnameable
from decoders.uss import parse_uss

#: Decodings kept for repeats, per generation of the memo: what a bus repeats stays while
#: one-off frames (changing values) pass through (an LRU that costs a dict lookup).
KEPT_DECODINGS = 8192
_REQUEST_CODE = ROLE_CODE[Role.REQUEST]
#: Frames of a batch :class:`_Fresh` reads the facts of one by one before it lists its columns.
_FACTS_ONE_BY_ONE = 256
#: Frames of a batch decoded one by one before its register reads may be decoded together;
#: they are once the new frames are this share of the frames passed. A read costs 1.1 µs
#: decoded with the others (all of them, repeats too), 2.6 µs alone (polling, 2026-11-25).
ONE_BY_ONE = 32
TOGETHER_FROM = 0.45
_NOISE_CODE = ROLE_CODE[Role.NOISE]
#: What of a request decoding its answer reads (see :func:`answer_context`).
AnswerContext = tuple[object, ...] | None
_NO_REQUEST: tuple[AnswerContext, Pdu | None] = (None, None)

#: What a message's decoding depends on: role code, protocol, bytes, its request's
#: :func:`answer_context` and the profiles' version.
DecodingKey = tuple[int, int, bytes, AnswerContext, int]


class Annotator:
    """Adds ``pdu``, ``params`` and ``summary`` to messages, in capture order."""

    def __init__(self, profiles: ProfileApplier | None = None) -> None:
        #: Open requests by frame index: their answer context and decoded PDU.
        self._requests: dict[int, tuple[AnswerContext, Pdu]] = {}
        self._profiles = profiles
        self._decodings: Memo[DecodingKey, tuple[Decoding, AnswerContext]] = Memo(KEPT_DECODINGS)
        #: Frames decoded from their values alone where one of their shape was decoded before.
        self._shapes = ValueShapes(profiles)

    @classmethod
    def naming_by(cls, book: ProfileBook | None) -> Annotator:
        """An annotator naming values by the profiles of ``book`` (``None``: naming none)."""
        return cls(ProfileApplier(book) if book is not None else None)

    def annotate_batch(self, batch: MessageBatch) -> AnnotatedBatch:
        """Every message of the batch, decoded; repeats share one :class:`Decoding`.
        Stays in columns: message objects are built only for frames not seen before."""
        decodings = self._annotate(batch, range(len(batch)), batch.role.tolist(), batch.frames.protocols().tolist(),
                                   batch.request_index.tolist())
        return AnnotatedBatch(batch, decodings)

    def annotate_columnar(self, batch: MessageBatch) -> AnnotatedBatch:
        """:meth:`annotate_batch`, but the commonest frames stay in columns
        (:mod:`decoders.modbus.columnar`, named by :mod:`decoders.profiles.column_names` where a
        profile names their slave): the result's ``columnar``, and its ``rows``
        the rest, decoded as there. The annotator's state after it is the same."""
        columnar = self._columnar(batch)
        if columnar is None:
            return self.annotate_batch(batch)
        first, requests = batch.frames.first_index, self._requests
        for index in columnar.earlier_requests:
            del requests[index]
        for position, function, address, count in columnar.kept():
            pdu = ReadRequest(function, address, count)
            requests[first + position] = (answer_context(pdu), pdu)
        rest = np.ones(len(batch), np.bool_)
        rest[columnar.positions] = False
        rows = np.flatnonzero(rest)
        decodings = self._annotate(batch, rows.tolist(), batch.role[rows].tolist(),
                                   batch.frames.protocols()[rows].tolist(), batch.request_index[rows].tolist())
        return AnnotatedBatch(batch, decodings, None, columnar)

    def _columnar(self, batch: MessageBatch) -> ColumnarFrames | None:
        """The frames of ``batch`` to keep in columns: Modbus frames whose profile adds nothing or
        names plainly (:mod:`decoders.profiles.columns`; a slave's frames after an identification
        in the batch that gives it another profile are named by that one, but from a second that
        gives it yet another on, which the plain path decodes), and frames a profile would do more
        to than name their params."""
        if not len(batch):
            return None
        profiles = self._profiles
        if profiles is None:
            return find_columnar(batch, self.plain_frames(batch), self._earlier_read)
        framed = frame_profiles(profiles, batch)
        nameable = framed.adds_nothing | np.array([plain_codes(profile) for profile in framed.profiles], np.bool_)
        eligible = (batch.frames.protocols() != USS) & nameable[framed.place]
        for slave, stop in framed.stops.items():
            eligible[stop:] &= batch.slave[stop:] != slave
        columnar = find_columnar(batch, eligible, self._earlier_read)
        if framed.adds_nothing.all():  # no profile names a frame of the batch
            return columnar
        learning = learning_slaves(profiles, batch, self._earlier_request, framed)
        while len(unnamed := unnameable(profiles, batch, columnar, learning, framed)):
            eligible[unnamed] = False
            columnar = find_columnar(batch, eligible, self._earlier_read)
        return named(profiles, batch, columnar, framed)

    def plain_frames(self, batch: MessageBatch) -> npt.NDArray[np.bool_]:
        """Which frames of ``batch`` are Modbus frames of slaves whose profile adds nothing now."""
        plain: npt.NDArray[np.bool_] = batch.frames.protocols() != USS
        if self._profiles is not None:
            slaves = distinct(batch.slave)
            adds_nothing = np.array([self._profiles.adds_nothing(int(slave)) for slave in slaves.tolist()], np.bool_)
            plain &= adds_nothing[np.searchsorted(slaves, batch.slave)]
        return plain

    def _earlier_request(self, index: int) -> Pdu | None:
        kept = self._requests.get(index)
        return None if kept is None else kept[1]

    def _earlier_read(self, index: int) -> tuple[int, int, int] | None:
        kept = self._requests.get(index)
        if kept is None or kept[0] is None or kept[0][0] is not ReadRequest:
            return None
        _, function, address, count = kept[0]
        return int(function), int(address), int(count)  # type: ignore[call-overload]

    def _annotate(self, batch: MessageBatch, positions: Iterable[int], roles: list[int], protocols: list[int],
                  request_indexes: list[int]) -> list[Decoding]:
        """The decodings of the messages at ``positions`` (the columns given: theirs), in a list
        by position (what no position names: :data:`IN_COLUMNS`)."""
        frames = batch.frames
        data, offsets, first = frames.data, frames.offsets.tolist(), frames.first_index
        decodings, requests, memo = [IN_COLUMNS] * len(batch), self._requests, self._decodings
        # Only decoding a frame teaches the profiles (a new version) or fills the memo.
        recent, version = memo.recent(), self._version()
        fresh = _Fresh(self, batch)
        for position, role, protocol, request_index in zip(positions, roles, protocols, request_indexes, strict=True):
            if request_index == NONE:
                context, request = _NO_REQUEST
            else:
                context, request = requests.pop(request_index, _NO_REQUEST)
                if first + position - request_index > KEPT_REQUESTS:
                    context, request = _NO_REQUEST  # too long ago: read against nothing
            key = (role, protocol, data[offsets[position] : offsets[position + 1]], context, version)
            known = recent(key)
            if known is None:
                known = memo.older(key)
                if known is None:
                    known = fresh.decode(position, key, request)
                    memo.put(key, known)
                    version = self._version()
                recent = memo.recent()
            if role == _REQUEST_CODE and known[0].pdu is not None:
                requests[first + position] = (known[1], known[0].pdu)
            decodings[position] = known[0]
        self._forget(first + len(batch))
        return decodings

    def _forget(self, next_index: int) -> None:
        """Requests no answer from ``next_index`` on reads against, let go (now and then)."""
        if len(self._requests) > 2 * KEPT_REQUESTS:
            oldest = next_index - KEPT_REQUESTS
            self._requests = {index: kept for index, kept in self._requests.items() if index >= oldest}

    def _version(self) -> int:
        return 0 if self._profiles is None else self._profiles.version

    def annotate_all(self, batch: MessageBatch) -> list[Message]:
        """:meth:`annotate_batch` as message objects."""
        return list(self.annotate_batch(batch))

    def annotate(self, message: Message) -> Message:
        """One message, decoded without the cache: the plain path the cache is tested against."""
        annotated = self._decode(message, self._open_request(message)[1])
        if annotated.role is Role.REQUEST:
            self._keep_request(annotated.frame.index, answer_context(annotated.pdu), annotated.pdu)
        return annotated

    def _open_request(self, message: Message) -> tuple[AnswerContext, Pdu | None]:
        """The context and PDU of the request ``message`` answers, if it is still kept."""
        if message.request_index is None:
            return _NO_REQUEST
        kept = self._requests.pop(message.request_index, _NO_REQUEST)
        return _NO_REQUEST if message.frame.index - message.request_index > KEPT_REQUESTS else kept

    def _keep_request(self, index: int, context: AnswerContext, pdu: Pdu | None) -> None:
        if pdu is not None:
            self._requests[index] = (context, pdu)
            self._forget(index + 1)

    def _decode(self, message: Message, request: Pdu | None) -> Message:
        frame = message.frame
        facts = FrameFacts(message.slave, message.role, message.function, frame.crc_ok)
        return message.with_decoding(self._decoding(frame.data, frame.protocol, facts, request))

    def _decoding(self, data: bytes, protocol: int, facts: FrameFacts, request: Pdu | None) -> Decoding:
        """What a frame says (``facts``: what the profiles read of it besides its bytes)."""
        role = facts.role
        if role is Role.NOISE:
            return Decoding(f"noise, {len(data)} byte{'s' if len(data) != 1 else ''}")
        if protocol == USS:
            telegram = parse_uss(data)
            decoding = Decoding(telegram.summary(), uss=telegram)
            request = None
        else:
            pdu = parse_as(data, role)
            summary = pdu.summary()
            if isinstance(pdu, ExceptionPdu):
                summary += f" ({function_name(pdu.function)})"
            if not facts.crc_ok:
                summary = f"CRC error: {summary}"
            decoding = LazyParams(summary, pdu, request)
        return self._profiled(decoding, facts, request)

    def _profiled(self, decoding: Decoding, facts: FrameFacts, request: Pdu | None) -> Decoding:
        """``decoding`` as the profiles name it (as it is, without profiles)."""
        return decoding if self._profiles is None else self._profiles.apply_decoding(decoding, facts, request)


class _Fresh:
    """Decodes the frames of a batch its annotator has not seen before: one by one
    (:meth:`Annotator._decoding`), or from their values where frames of their shape were
    decoded before (:mod:`decoders.modbus.value_shapes`), while they are few (the first
    :data:`ONE_BY_ONE`, or fewer than :data:`TOGETHER_FROM` of the frames passed); from then
    on, the register reads and their answers of slaves no profile names at once
    (:func:`register_reads`: cheaper than by their shape), the rest as before; then the
    profiles, which may learn. A batch of repeats has few frames to decode, and decoding all
    its reads for them would cost more than they do."""

    def __init__(self, annotator: Annotator, batch: MessageBatch) -> None:
        self._annotator, self._batch = annotator, batch
        self._facts: tuple[list[int], list[bool], list[int]] | None = None
        self._reads: dict[int, QuickRead] = {}
        self._decoded = 0
        self._together = False

    def decode(self, position: int, key: DecodingKey, request: Pdu | None) -> tuple[Decoding, AnswerContext]:
        annotator, batch = self._annotator, self._batch
        slave, crc_ok, function = self._facts_of(position)
        self._decoded += 1
        if not self._together and self._decoded > ONE_BY_ONE and self._decoded >= TOGETHER_FROM * (position + 1):
            # A named slave's reads go by their shape (value_shapes), for less.
            eligible = annotator.plain_frames(batch)
            eligible[:position] = False  # decoded already, or repeats
            self._reads, self._together = register_reads(batch, eligible), True
        read = self._reads.get(position)
        profiles = annotator._profiles
        if read is not None and (profiles is None or profiles.adds_nothing(slave)):
            return LazyParams(read[0], read[1], request), read[2]  # what _profiled would leave as it is
        shaped = annotator._shapes.decode(key, crc_ok, request)
        if shaped is not None:
            return shaped
        role, protocol, data = key[0], key[1], key[2]
        facts = FrameFacts(None if slave == NONE else slave, ROLE_ORDER[role], None if function == NONE else function,
                           crc_ok)
        if read is None:
            decoding = annotator._decoding(data, protocol, facts, request)
            decoded: tuple[Decoding, AnswerContext] = (decoding, answer_context(decoding.pdu))
        else:
            decoded = (annotator._profiled(LazyParams(read[0], read[1], request), facts, request), read[2])
        annotator._shapes.learn(key, facts, request, decoded, annotator._version())
        return decoded

    def _facts_of(self, position: int) -> tuple[int, bool, int]:
        """The slave, CRC and function of the frame at ``position``: read one by one while few
        are decoded (a batch of repeats decodes a few dozen: making lists of its columns took
        0.8 ms a batch, 24 ms of 1 M steady frames), from lists once many are."""
        batch = self._batch
        if self._facts is None:
            if self._decoded < _FACTS_ONE_BY_ONE:
                return int(batch.slave[position]), bool(batch.frames.crc_ok[position]), int(batch.function[position])
            self._facts = batch.slave.tolist(), batch.frames.crc_ok.tolist(), batch.function.tolist()
        slaves, crc, functions = self._facts
        return slaves[position], crc[position], functions[position]


def answer_context(request: Pdu | None) -> AnswerContext:
    """What decoding an answer reads of its request: the request's kind and address ranges,
    never the values it writes (:func:`named_registers` and the profiles' exception notes
    read no more). Answers to requests that differ only in written values decode alike,
    so they share a cached decoding."""
    match request:
        case None:
            return None
        case ReadRequest(function=function, address=address, count=count):
            return (ReadRequest, function, address, count)
        case ReadWriteRequest():
            read, write = (request.read_address, request.read_count), (request.write_address, request.write_count)
            return (ReadWriteRequest, *read, *write)
        case WriteRegistersRequest(address=address, count=count) | WriteCoilsRequest(address=address, count=count):
            return (type(request), address, count)
    return (type(request), getattr(request, "address", None))
