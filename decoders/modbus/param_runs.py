"""The registers or coils a frame names, as runs of consecutive addresses: the columnar form.

A register answer names ``count`` registers from its request's address, with one value each; a
read request names them without values. Written out as one :class:`~decoders.message.ParamValue`
per register, a coil read of 64 coils is 64 objects; as a :class:`ParamRun` it is one address,
one count and the values as they were decoded. Outputs that know no profile applies (JSONL,
the MCAP ``/slave/N/params`` channel) write runs straight from here, and
:func:`named_registers` -- the one rule -- expands the same runs into params, so both forms say
the same by construction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

from decoders.message import Decoding, ParamValue
from decoders.modbus.pdu import (
    COIL_ON,
    BitsResponse,
    MaskWrite,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    RegistersResponse,
    WriteCoilsRequest,
    WriteMultipleResponse,
    WriteRegistersRequest,
    WriteSingle,
    quantity_allowed,
)


class ParamRun(NamedTuple):
    """``size`` consecutive registers or coils from ``address``; ``values``: their raw values
    (coils as 0 and 1), or ``None`` where the frame names them without values (a read request).
    A tuple: one is built for every frame decoded anew, and a frozen dataclass costs a setattr
    per field."""

    address: int
    size: int
    values: Sequence[int] | None = None

    def addresses(self) -> range:
        return range(self.address, self.address + self.size)


def param_runs(pdu: Pdu, request: Pdu | None) -> tuple[ParamRun, ...]:
    """The runs ``pdu`` names (read against ``request``, its answer's request); none for a
    request for more than Modbus allows (a damaged count would name thousands).

    One function per PDU type, looked up by the type: a ``match`` over class patterns tries
    them in turn, which cost more than the run itself for most frames."""
    runs_of = _RUNS_BY_TYPE.get(type(pdu))
    return () if runs_of is None else runs_of(pdu, request)


def _counted(pdu: ReadRequest | WriteMultipleResponse, request: Pdu | None) -> tuple[ParamRun, ...]:
    return (ParamRun(pdu.address, pdu.count),) if quantity_allowed(pdu) else ()


def _registers(pdu: RegistersResponse, request: Pdu | None) -> tuple[ParamRun, ...]:
    start = _read_start(request)
    return () if start is None else (ParamRun(start, len(pdu.values), pdu.values),)


def _bits(pdu: BitsResponse, request: Pdu | None) -> tuple[ParamRun, ...]:
    if not isinstance(request, ReadRequest):
        return ()
    asked = pdu.bits[: request.count]
    return (ParamRun(request.address, len(asked), asked),)


def _single(pdu: WriteSingle, request: Pdu | None) -> tuple[ParamRun, ...]:
    if pdu.function == 5:  # FC 5: a coil, written as 0xFF00 or 0x0000
        return (ParamRun(pdu.address, 1, (1 if pdu.value == COIL_ON else 0,)),)
    return (ParamRun(pdu.address, 1, (pdu.value,)),)


def _written_registers(pdu: WriteRegistersRequest, request: Pdu | None) -> tuple[ParamRun, ...]:
    return (ParamRun(pdu.address, len(pdu.values), pdu.values),)


def _written_coils(pdu: WriteCoilsRequest, request: Pdu | None) -> tuple[ParamRun, ...]:
    return (ParamRun(pdu.address, len(pdu.bits), pdu.bits),)


def _read_write(pdu: ReadWriteRequest, request: Pdu | None) -> tuple[ParamRun, ...]:
    if not quantity_allowed(pdu):
        return ()
    return (ParamRun(pdu.write_address, len(pdu.values), pdu.values), ParamRun(pdu.read_address, pdu.read_count))


def _masked(pdu: MaskWrite, request: Pdu | None) -> tuple[ParamRun, ...]:
    return (ParamRun(pdu.address, 1),)


_RUNS_BY_TYPE: dict[type, Callable[[Any, Pdu | None], tuple[ParamRun, ...]]] = {
    ReadRequest: _counted,
    WriteMultipleResponse: _counted,
    RegistersResponse: _registers,
    BitsResponse: _bits,
    WriteSingle: _single,
    WriteRegistersRequest: _written_registers,
    WriteCoilsRequest: _written_coils,
    ReadWriteRequest: _read_write,
    MaskWrite: _masked,
}


def named_registers(pdu: Pdu, request: Pdu | None) -> tuple[ParamValue, ...]:
    """The registers or coils ``pdu`` names, with their raw values where it carries them:
    :func:`param_runs` a param each."""
    return expand_runs(param_runs(pdu, request))


def expand_runs(runs: tuple[ParamRun, ...]) -> tuple[ParamValue, ...]:
    """A :class:`~decoders.message.ParamValue` per register or coil of ``runs``."""
    params: list[ParamValue] = []
    for run in runs:
        if run.values is None:
            params += map(ParamValue, run.addresses())
        else:
            params += [ParamValue(address, None, None, value, value)
                       for address, value in zip(run.addresses(), run.values, strict=True)]
    return tuple(params)


def _read_start(request: Pdu | None) -> int | None:
    if isinstance(request, ReadRequest):
        return request.address
    if isinstance(request, ReadWriteRequest):
        return request.read_address
    return None


def addressed_values(decoding: Decoding) -> list[tuple[int, int | None]]:
    """The address and raw value (``None``: named without one) of every register or coil a
    decoding names."""
    return [(param.address, param.raw) for param in decoding.params]
