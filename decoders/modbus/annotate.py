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
again, never answered from before.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.frame import USS
from decoders.memo import Memo
from decoders.message import (
    NONE,
    ROLE_CODE,
    ROLE_ORDER,
    AnnotatedBatch,
    Decoding,
    Message,
    MessageBatch,
    ParamValue,
    Role,
)
from decoders.modbus.codes import function_name
from decoders.modbus.layouts import fits_request
from decoders.modbus.param_runs import ParamRun, expand_runs, named_registers, param_runs
from decoders.modbus.pdu import (
    DeviceIdResponse,
    ExceptionPdu,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    WriteCoilsRequest,
    WriteRegistersRequest,
    parse_pdu,
)
from decoders.modbus.quick import QuickRead, register_reads
from decoders.profiles.apply import ProfileApplier
from decoders.uss import parse_uss

#: Decoded requests kept for their responses; older ones are answered or lost.
KEPT_REQUESTS = 1024
#: Decodings kept for repeats, per generation of the memo: what a bus repeats stays while
#: one-off frames (changing values) pass through (an LRU that costs a dict lookup).
KEPT_DECODINGS = 8192
_AS_REQUEST = {Role.REQUEST, Role.BROADCAST}
_REQUEST_CODE = ROLE_CODE[Role.REQUEST]
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
        self._requests: OrderedDict[int, tuple[AnswerContext, Pdu]] = OrderedDict()
        self._profiles = profiles
        self._decodings: Memo[DecodingKey, tuple[Decoding, AnswerContext]] = Memo(KEPT_DECODINGS)

    def annotate_batch(self, batch: MessageBatch) -> AnnotatedBatch:
        """Every message of the batch, decoded; repeats share one :class:`Decoding`.
        Stays in columns: message objects are built only for frames not seen before."""
        frames = batch.frames
        data, offsets, first = frames.data, frames.offsets.tolist(), frames.first_index
        rows = zip(batch.role.tolist(), frames.protocols().tolist(), batch.request_index.tolist(), strict=True)
        decodings, requests, memo = [], self._requests, self._decodings
        # Only decoding a frame teaches the profiles (a new version) or fills the memo.
        recent, version = memo.recent(), self._version()
        fresh = _Fresh(self, batch)
        for position, (role, protocol, request_index) in enumerate(rows):
            context, request = _NO_REQUEST if request_index == NONE else requests.pop(request_index, _NO_REQUEST)
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
                if len(requests) > KEPT_REQUESTS:
                    requests.popitem(last=False)
            decodings.append(known[0])
        return AnnotatedBatch(batch, decodings)

    def _lean_rows(self, batch: MessageBatch) -> npt.NDArray[np.bool_]:
        """The Modbus frames of slaves whose profile adds nothing (see :meth:`_lean`)."""
        lean = batch.frames.protocols() != USS
        if self._profiles is not None:
            slaves = np.unique(batch.slave).tolist()
            profiled = [slave for slave in slaves if not self._profiles.adds_nothing(slave)]
            if profiled:
                lean &= ~np.isin(batch.slave, profiled)
        return np.asarray(lean, np.bool_)

    def _lean(self, data: bytes, role: int, protocol: int, slave: int, *, crc_ok: bool,
              request: Pdu | None) -> Decoding | None:
        """A Modbus frame of a slave whose profile adds nothing, decoded without message objects,
        its params named when first read (a table reads summaries only); ``None`` for the rest
        (noise, USS, profiled slaves, identifications), which :meth:`_decode` decodes."""
        if protocol == USS or role == _NOISE_CODE:
            return None
        profiles = self._profiles
        if profiles is not None and not profiles.adds_nothing(slave):
            return None
        kind = ROLE_ORDER[role]
        is_request = kind in _AS_REQUEST or (kind is Role.UNKNOWN and fits_request(data))
        pdu = parse_pdu(data, is_request=is_request)
        if profiles is not None and isinstance(pdu, DeviceIdResponse):
            return None  # an identification may choose the slave's profile
        summary = pdu.summary()
        if isinstance(pdu, ExceptionPdu):
            summary += f" ({function_name(pdu.function)})"
        if not crc_ok:
            summary = f"CRC error: {summary}"
        return LazyParams(summary, pdu, request)

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
        return self._requests.pop(message.request_index, _NO_REQUEST)

    def _keep_request(self, index: int, context: AnswerContext, pdu: Pdu | None) -> None:
        if pdu is not None:
            self._requests[index] = (context, pdu)
            if len(self._requests) > KEPT_REQUESTS:
                self._requests.popitem(last=False)

    def _decode(self, message: Message, request: Pdu | None) -> Message:
        frame = message.frame
        if message.role is Role.NOISE:
            return message.decoded(summary=f"noise, {len(frame.data)} byte{'s' if len(frame.data) != 1 else ''}")
        if frame.protocol == USS:
            return self._uss(message)
        is_request = message.role in _AS_REQUEST or (message.role is Role.UNKNOWN and fits_request(frame.data))
        pdu = parse_pdu(frame.data, is_request=is_request)
        summary = pdu.summary()
        if isinstance(pdu, ExceptionPdu):
            summary += f" ({function_name(pdu.function)})"
        if not frame.crc_ok:
            summary = f"CRC error: {summary}"
        annotated = message.decoded(summary=summary, params=named_registers(pdu, request), pdu=pdu)
        return annotated if self._profiles is None else self._profiles.apply(annotated, request)


    def _uss(self, message: Message) -> Message:
        telegram = parse_uss(message.frame.data)
        annotated = message.decoded(summary=telegram.summary(), uss=telegram)
        return annotated if self._profiles is None else self._profiles.apply(annotated, None)


class _Fresh:
    """Decodes the frames of a batch its annotator has not seen before: register reads of slaves
    no profile speaks for from :func:`register_reads` (the whole batch at once, when the first
    such frame comes), other frames of those slaves by :meth:`Annotator._lean`, the rest by
    :meth:`Annotator._decode` -- the one path that may teach the profiles something, after
    which which slaves are lean is asked again."""

    def __init__(self, annotator: Annotator, batch: MessageBatch) -> None:
        self._annotator, self._batch = annotator, batch
        self._reads: dict[int, QuickRead] | None = None
        self._messages = batch.rows()

    def decode(self, position: int, key: DecodingKey, request: Pdu | None) -> tuple[Decoding, AnswerContext]:
        annotator, batch = self._annotator, self._batch
        if self._reads is None:
            self._slaves, self._crc = batch.slave.tolist(), batch.frames.crc_ok.tolist()
            self._reads = register_reads(batch, annotator._lean_rows(batch))
        read = self._reads.get(position)
        if read is not None:
            return LazyParams(read[0], read[1], request), read[2]
        role, protocol, data = key[0], key[1], key[2]
        decoding = annotator._lean(data, role, protocol, self._slaves[position], crc_ok=self._crc[position],
                                   request=request)
        if decoding is None:
            version = annotator._version()
            decoding = annotator._decode(self._messages[position], request).decoding
            if annotator._version() != version:  # the profiles learnt: which slaves are lean may change
                self._reads = None
        return decoding, answer_context(decoding.pdu)


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


#: Where a :class:`Decoding` keeps its params (the slot :class:`LazyParams` fills when read).
_PARAMS_SLOT: Any = Decoding.__dict__["params"]


class LazyParams(Decoding):
    """A decoding no profile adds to, whose params are named when first read, from its PDU and
    its request's: the same tuple :func:`named_registers` gives, built only for outputs that
    read params (a table reads the summary alone, and building a param per register is most of
    the cost of a frame never seen before). Outputs that write params as text or columns read
    :attr:`runs` instead and build none."""

    __slots__ = ("_request", "_runs")

    def __init__(self, summary: str, pdu: Pdu, request: Pdu | None) -> None:
        # Not Decoding.__init__: its dataclass code would assign ``params`` through this
        # class's property; the other fields are plain slots.
        self.summary = summary
        self.pdu = pdu
        self.remarks = ()
        self.device = None
        self.uss = None
        self._request = request
        self._runs: tuple[ParamRun, ...] | None = None

    @property
    def runs(self) -> tuple[ParamRun, ...]:
        """The params as runs of consecutive addresses (:func:`param_runs`)."""
        if self._runs is None:
            assert self.pdu is not None
            self._runs = param_runs(self.pdu, self._request)
            self._request = None
        return self._runs

    @property
    def params(self) -> tuple[ParamValue, ...]:  # type: ignore[override]
        try:
            named: tuple[ParamValue, ...] = _PARAMS_SLOT.__get__(self, Decoding)
        except AttributeError:
            named = expand_runs(self.runs)
            _PARAMS_SLOT.__set__(self, named)
        return named
