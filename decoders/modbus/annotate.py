"""What each message says: its decoded PDU, the registers or coils it names, one summary line.

Responses are read against their request (a register response carries values, its
request the addresses), so the annotator keeps the decoded requests that still
await an answer.
"""

from __future__ import annotations

from collections import OrderedDict

from decoders.frame import USS
from decoders.message import Message, MessageBatch, ParamValue, Role
from decoders.modbus.codes import function_name
from decoders.modbus.layouts import fits_request
from decoders.modbus.pdu import (
    COIL_ON,
    BitsResponse,
    ExceptionPdu,
    MaskWrite,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    RegistersResponse,
    WriteCoilsRequest,
    WriteMultipleResponse,
    WriteRegistersRequest,
    WriteSingle,
    parse_pdu,
)
from decoders.profiles.apply import ProfileApplier
from decoders.uss import parse_uss

#: Decoded requests kept for their responses; older ones are answered or lost.
KEPT_REQUESTS = 1024
_AS_REQUEST = {Role.REQUEST, Role.BROADCAST}


class Annotator:
    """Adds ``pdu``, ``params`` and ``summary`` to messages, in capture order."""

    def __init__(self, profiles: ProfileApplier | None = None) -> None:
        self._requests: OrderedDict[int, Pdu] = OrderedDict()
        self._profiles = profiles

    def annotate_all(self, messages: MessageBatch) -> list[Message]:
        return [self.annotate(m) for m in messages]

    def annotate(self, message: Message) -> Message:
        frame = message.frame
        if message.role is Role.NOISE:
            return message.decoded(summary=f"noise, {len(frame.data)} byte{'s' if len(frame.data) != 1 else ''}")
        if frame.protocol == USS:
            return self._uss(message)
        is_request = message.role in _AS_REQUEST or (message.role is Role.UNKNOWN and fits_request(frame.data))
        pdu = parse_pdu(frame.data, is_request=is_request)
        request = None
        if message.request_index is not None:
            request = self._requests.pop(message.request_index, None)
        if message.role is Role.REQUEST:
            self._requests[frame.index] = pdu
            if len(self._requests) > KEPT_REQUESTS:
                self._requests.popitem(last=False)
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


def named_registers(pdu: Pdu, request: Pdu | None) -> tuple[ParamValue, ...]:
    """The registers or coils ``pdu`` names, with their raw values where it carries them."""
    match pdu:
        case ReadRequest(address=address, count=count) | WriteMultipleResponse(address=address, count=count):
            return tuple(ParamValue(address + i, None) for i in range(count))
        case RegistersResponse(values=values):
            start = _read_start(request)
            return () if start is None else tuple(ParamValue(start + i, v, value=v) for i, v in enumerate(values))
        case BitsResponse(bits=bits) if isinstance(request, ReadRequest):
            asked = bits[: request.count]
            return tuple(ParamValue(request.address + i, int(b), value=int(b)) for i, b in enumerate(asked))
        case WriteSingle(function=5, address=address, value=value):
            bit = 1 if value == COIL_ON else 0
            return (ParamValue(address, bit, value=bit),)
        case WriteSingle(address=address, value=value):
            return (ParamValue(address, value, value=value),)
        case WriteRegistersRequest(address=address, values=values):
            return tuple(ParamValue(address + i, v, value=v) for i, v in enumerate(values))
        case WriteCoilsRequest(address=address, bits=bits):
            return tuple(ParamValue(address + i, int(b), value=int(b)) for i, b in enumerate(bits))
        case ReadWriteRequest():
            written = tuple(ParamValue(pdu.write_address + i, v, value=v) for i, v in enumerate(pdu.values))
            return written + tuple(ParamValue(pdu.read_address + i, None) for i in range(pdu.read_count))
        case MaskWrite(address=address):
            return (ParamValue(address, None),)
    return ()


def _read_start(request: Pdu | None) -> int | None:
    if isinstance(request, ReadRequest):
        return request.address
    if isinstance(request, ReadWriteRequest):
        return request.read_address
    return None
