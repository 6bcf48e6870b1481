"""What each message says: its decoded PDU, the registers or coils it names, one summary line.

Responses are read against their request (a register response carries values, its
request the addresses), so the annotator keeps the decoded requests that still
await an answer.

Which frames are decoded how depends on the frames alone: :meth:`Annotator.annotate_columnar`
keeps the reads, writes and answers of FC 1-6, 15, 16 and 23 that are well formed and paired
in columns (:mod:`decoders.modbus.columnar`, found by
:mod:`decoders.modbus.columnar_find`; named by :mod:`decoders.profiles.column_names`), and
decodes the rest one by one through the PDU parser (:meth:`Annotator.annotate_batch`).

A bus repeats itself: what a frame says depends only on its bytes, role and protocol, what its
request asked (:func:`answer_context`) and what the profiles know at that moment, so the rest
is decoded once per such combination, and every repeat gets the same :class:`Decoding`. The
profiles' ``version`` is part of the key: a frame that taught them something (a scanner table,
an identification) is decoded again, never answered from before.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch
from decoders.distinct import distinct
from decoders.frame import USS
from decoders.memo import KEPT_DECODINGS, Memo
from decoders.message import (
    IN_COLUMNS,
    NONE,
    ROLE_CODE,
    ROLE_ORDER,
    Decoding,
    MessageBatch,
    Role,
    slice_messages,
)
from decoders.modbus.codecs import parse_as
from decoders.modbus.codes import function_name
from decoders.modbus.columnar import KEPT_REQUESTS, ColumnarFrames, joined
from decoders.modbus.columnar_find import find_columnar
from decoders.modbus.param_runs import named_registers
from decoders.modbus.pdu import (
    ExceptionPdu,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    WriteCoilsRequest,
    WriteRegistersRequest,
)
from decoders.profiles.apply import FrameFacts, ProfileApplier
from decoders.profiles.book import ProfileBook
from decoders.profiles.column_names import named
from decoders.profiles.columns import FrameProfiles, first_change, frame_profiles, plain_codes, unnameable
from decoders.uss import parse_uss

_REQUEST_CODE = ROLE_CODE[Role.REQUEST]
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
        """Every message of the batch decoded: the commonest frames in columns
        (:mod:`decoders.modbus.columnar`, named by :mod:`decoders.profiles.column_names` where a
        profile names their slave), the rest one by one as :meth:`annotate_batch` does them. The
        batch is decoded in parts, cut after each frame that changes what the profiles name
        (:func:`~decoders.profiles.columns.first_change`: an identification, a scanner mapping
        learnt), so that each part is named in one step by the profiles as they stand at its
        start, then joined. The annotator's state after it is that of :meth:`annotate_batch`."""
        parts: list[tuple[int, AnnotatedBatch]] = []
        start, profiles = 0, self._profiles
        while True:
            rest = batch if start == 0 else slice_messages(batch, start, len(batch))
            framed = None if profiles is None or not len(rest) else frame_profiles(profiles, rest)
            change = None if profiles is None or framed is None else \
                first_change(profiles, rest, self._earlier_request, framed)
            stop = len(batch) if change is None else start + change + 1
            part = rest if stop == len(batch) else slice_messages(batch, start, stop)
            parts.append((start, self._annotate_part(part, None if framed is None else framed.head(len(part)))))
            if stop == len(batch):
                break
            start = stop
        if len(parts) == 1:
            return parts[0][1]
        offsets = batch.frames.offsets
        columnar = joined([(start, int(offsets[start] - offsets[0]), part.columnar) for start, part in parts])
        return AnnotatedBatch(batch, [decoding for _, part in parts for decoding in part.decoded], None, columnar)

    def _annotate_part(self, batch: MessageBatch, framed: FrameProfiles | None) -> AnnotatedBatch:
        """A part of :meth:`annotate_columnar` (``framed``: its frames' profiles, ``None`` without
        profiles): its frames in columns, and the rest one by one."""
        columnar = self._columnar(batch, framed)
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

    def _columnar(self, batch: MessageBatch, framed: FrameProfiles | None) -> ColumnarFrames | None:
        """The frames of ``batch`` to keep in columns: Modbus frames whose profile adds nothing or
        names plainly (:mod:`decoders.profiles.columns`), but not those it would do more to than
        name their params."""
        if not len(batch):
            return None
        profiles = self._profiles
        if profiles is None or framed is None:
            return find_columnar(batch, self.plain_frames(batch), self._earlier_read)
        nameable = framed.adds_nothing | np.array([plain_codes(profile) for profile in framed.profiles], np.bool_)
        eligible = (batch.frames.protocols() != USS) & nameable[framed.place]
        columnar = find_columnar(batch, eligible, self._earlier_read)
        if framed.adds_nothing.all():  # no profile names a frame of the batch
            return columnar
        while len(unnamed := unnameable(profiles, batch, columnar, framed)):
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
                    known = self._decode_new(batch, position, key, request)
                    memo.put(key, known)
                    version = self._version()
                recent = memo.recent()
            if role == _REQUEST_CODE and known[0].pdu is not None:
                requests[first + position] = (known[1], known[0].pdu)
            decodings[position] = known[0]
        self._forget(first + len(batch))
        return decodings

    def _decode_new(self, batch: MessageBatch, position: int, key: DecodingKey,
                    request: Pdu | None) -> tuple[Decoding, AnswerContext]:
        """A frame new to the memo, by :meth:`_decoding`, with the context its answer reads."""
        slave, function = int(batch.slave[position]), int(batch.function[position])
        facts = FrameFacts(None if slave == NONE else slave, ROLE_ORDER[key[0]],
                           None if function == NONE else function, bool(batch.frames.crc_ok[position]))
        decoding = self._decoding(key[2], key[1], facts, request)
        return decoding, answer_context(decoding.pdu)

    def _forget(self, next_index: int) -> None:
        """Requests no answer from ``next_index`` on reads against, let go (now and then)."""
        if len(self._requests) > 2 * KEPT_REQUESTS:
            oldest = next_index - KEPT_REQUESTS
            self._requests = {index: kept for index, kept in self._requests.items() if index >= oldest}

    def _version(self) -> int:
        return 0 if self._profiles is None else self._profiles.version

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
            decoding = Decoding(summary, named_registers(pdu, request), pdu)
        return self._profiled(decoding, facts, request)

    def _profiled(self, decoding: Decoding, facts: FrameFacts, request: Pdu | None) -> Decoding:
        """``decoding`` as the profiles name it (as it is, without profiles)."""
        return decoding if self._profiles is None else self._profiles.apply_decoding(decoding, facts, request)


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
