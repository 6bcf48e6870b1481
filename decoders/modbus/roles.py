"""A first guess at each frame's role from its content and its position.

The length rules say whether a frame has the shape of a request, of a response, or
of both (FC 5/6/8 echoes are byte-identical); where both fit, the order decides: a
frame that repeats the shape of an open request to the same slave is its answer.
"""

from __future__ import annotations

from functools import cache

from decoders.frame import Frame
from decoders.message import Message, Role
from decoders.modbus.codes import EXCEPTION_BIT, exception_name, function_name
from decoders.modbus.layouts import MEI_EXCEPTION_LENGTH, fits_request, fits_response

BROADCAST_ADDRESS = 0


class RoleGuesser:
    """Classifies frames one after another; remembers the last open request."""

    def __init__(self) -> None:
        self._open_request: tuple[int, int] | None = None

    def classify(self, frame: Frame) -> Message:
        data = frame.data
        if frame.is_noise:
            return _message(frame, Role.NOISE, f"noise, {len(data)} bytes")
        if len(data) < 4:
            self._open_request = None
            function = data[1] & 0x7F if len(data) > 1 else None
            return _message(frame, Role.UNKNOWN, f"{len(data)}-byte fragment", slave=data[0], function=function)
        slave, function = data[0], data[1] & 0x7F
        role = self._role(data)
        exception_code = None
        if role is Role.EXCEPTION:
            exception_code = data[3] if len(data) == MEI_EXCEPTION_LENGTH else data[2]
        self._open_request = (slave, function) if role is Role.REQUEST else None
        summary = _summary(role, function, exception_code)
        return _message(frame, role, summary, slave=slave, function=function, exception_code=exception_code)

    def _role(self, data: bytes) -> Role:
        if data[1] & EXCEPTION_BIT:
            return Role.EXCEPTION if fits_response(data) else Role.UNKNOWN
        as_request, as_response = fits_request(data), fits_response(data)
        if as_request and as_response:
            as_request = self._open_request != (data[0], data[1])
        if as_request:
            return Role.BROADCAST if data[0] == BROADCAST_ADDRESS else Role.REQUEST
        return Role.RESPONSE if as_response else Role.UNKNOWN



def _message(
    frame: Frame,
    role: Role,
    summary: str,
    *,
    slave: int | None = None,
    function: int | None = None,
    exception_code: int | None = None,
) -> Message:
    if not frame.crc_ok and role is not Role.NOISE:
        summary = f"CRC error: {summary}"
    return Message(frame, role, slave, function, exception_code, summary, frame.flags)


@cache
def _summary(role: Role, function: int, exception_code: int | None) -> str:
    name = function_name(function)
    if exception_code is not None:
        return f"exception {exception_code:02X} {exception_name(exception_code)} ({name})"
    if role is Role.UNKNOWN:
        return f"{name}, length fits no layout"
    return f"{name} {role.value}"
