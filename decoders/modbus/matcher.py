"""Roles and pairing on one wire: which frame asks, which answers, and what went unanswered.

A passive tap sees requests and responses interleaved on one line. The matcher
decides each frame's role from its shape (the length rules), its position and the
requests still open, pairs every response and exception with its request, and flags
``timeout``, ``retry`` and ``unexpected``.

* Requests are open per slave address, so two masters polling different slaves
  interleave without disturbing each other.
* A frame that has the shape of both a request and a response (FC 5/6/8/22 echoes
  are byte-identical) is the response when it answers the open request to its
  slave, else a request: order decides, not guessing.
* A response answers an open request when slave and function agree and its
  content fits the request (byte count for the registers asked, echoed address,
  sub-function or MEI type).
* A request is ``timeout`` when another request to the same slave comes first, or
  when the response timeout passes (fixed, or derived from the traffic: ten times
  the longest recent latency, at least 100 ms, at most 1 s).
* A request is ``retry`` when it repeats, byte for byte, the previous request to
  that slave that got no valid answer.
* Address 0 is a broadcast: nobody answers it, and a frame that looks like an
  answer to it is ``unexpected``.

A request is held back until its outcome is known, and frames behind it with it,
so that messages leave in capture order with their flags final.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from decoders.frame import Frame, FrameFlag
from decoders.framing.content import MIN_ADU
from decoders.message import Message, Role
from decoders.modbus.codes import EXCEPTION_BIT
from decoders.modbus.layouts import MEI_EXCEPTION_LENGTH, fits_request, fits_response

BROADCAST_ADDRESS = 0
MIN_TIMEOUT_NS = 100_000_000
MAX_TIMEOUT_NS = 1_000_000_000
TIMEOUT_PER_LATENCY = 10
LATENCY_WINDOW = 256


@dataclass(slots=True)
class Draft:
    """A message whose flags may still change."""

    frame: Frame
    role: Role
    slave: int | None
    function: int | None
    exception_code: int | None = None
    flags: FrameFlag = FrameFlag.NONE
    request_index: int | None = None
    latency_ns: int | None = None
    open: bool = False

    def message(self) -> Message:
        return Message(
            frame=self.frame,
            role=self.role,
            slave=self.slave,
            function=self.function,
            exception_code=self.exception_code,
            summary="",
            flags=self.flags | self.frame.flags,
            request_index=self.request_index,
            latency_ns=self.latency_ns,
        )


@dataclass
class Matcher:
    """Feeds frames in capture order; returns messages whose flags are final."""

    response_timeout_ns: int | None = None
    _held: deque[Draft] = field(default_factory=deque)
    _open: dict[int, Draft] = field(default_factory=dict)
    _failed: dict[int, bytes] = field(default_factory=dict)
    _last_broadcast: bytes | None = None
    _latencies: deque[int] = field(default_factory=lambda: deque(maxlen=LATENCY_WINDOW))
    _adaptive_timeout_ns: int = MAX_TIMEOUT_NS

    @property
    def timeout_ns(self) -> int:
        """The response timeout in force."""
        return self.response_timeout_ns if self.response_timeout_ns is not None else self._adaptive_timeout_ns

    def feed(self, frames: Iterable[Frame]) -> list[Message]:
        for frame in frames:
            self._expire(frame.t_start_ns)
            self._held.append(self._classify(frame))
        return self._release()

    def flush(self) -> list[Message]:
        """At the end of the capture: requests still open stay without a verdict."""
        for draft in self._open.values():
            draft.open = False
        self._open.clear()
        return self._release()

    def _release(self) -> list[Message]:
        released = []
        while self._held and not self._held[0].open:
            released.append(self._held.popleft().message())
        return released

    def _expire(self, now_ns: int) -> None:
        deadline = now_ns - self.timeout_ns
        for slave, draft in list(self._open.items()):
            if draft.frame.t_end_ns < deadline:
                self._fail(slave, draft)

    def _fail(self, slave: int, draft: Draft) -> None:
        draft.flags |= FrameFlag.TIMEOUT
        draft.open = False
        self._failed[slave] = draft.frame.data
        del self._open[slave]

    def _classify(self, frame: Frame) -> Draft:
        data = frame.data
        if frame.is_noise:
            return Draft(frame, Role.NOISE, None, None)
        if len(data) < MIN_ADU:
            return Draft(frame, Role.UNKNOWN, data[0], data[1] & ~EXCEPTION_BIT if len(data) > 1 else None)
        slave, raw_function = data[0], data[1]
        if raw_function & EXCEPTION_BIT:
            return self._exception(frame, slave, raw_function & ~EXCEPTION_BIT)
        as_request, as_response = fits_request(data), fits_response(data)
        if slave == BROADCAST_ADDRESS:
            return self._broadcast(frame, as_request, as_response)
        pending = self._open.get(slave)
        if as_response and pending is not None and _answers(pending.frame.data, data):
            return self._answer(frame, pending, Draft(frame, Role.RESPONSE, slave, raw_function))
        if as_request:
            return self._request(frame, slave, raw_function)
        draft = Draft(frame, Role.RESPONSE if as_response else Role.UNKNOWN, slave, raw_function)
        if as_response:
            draft.flags |= FrameFlag.UNEXPECTED
        return draft

    def _exception(self, frame: Frame, slave: int, function: int) -> Draft:
        data = frame.data
        if not fits_response(data):
            return Draft(frame, Role.UNKNOWN, slave, function)
        code = data[3] if len(data) == MEI_EXCEPTION_LENGTH else data[2]
        draft = Draft(frame, Role.EXCEPTION, slave, function, exception_code=code)
        pending = self._open.get(slave)
        if slave != BROADCAST_ADDRESS and pending is not None and pending.function == function:
            return self._answer(frame, pending, draft)
        draft.flags |= FrameFlag.UNEXPECTED
        return draft

    def _broadcast(self, frame: Frame, as_request: bool, as_response: bool) -> Draft:
        data = frame.data
        replies = as_response and self._last_broadcast is not None and _answers(self._last_broadcast, data)
        if as_request and not replies:
            self._last_broadcast = data
            return Draft(frame, Role.BROADCAST, BROADCAST_ADDRESS, data[1])
        draft = Draft(frame, Role.RESPONSE if as_response else Role.UNKNOWN, BROADCAST_ADDRESS, data[1])
        if as_response:
            draft.flags |= FrameFlag.UNEXPECTED
        return draft

    def _request(self, frame: Frame, slave: int, function: int) -> Draft:
        superseded = self._open.get(slave)
        if superseded is not None:
            self._fail(slave, superseded)
        draft = Draft(frame, Role.REQUEST, slave, function, open=True)
        if self._failed.get(slave) == frame.data:
            draft.flags |= FrameFlag.RETRY
        self._open[slave] = draft
        return draft

    def _answer(self, frame: Frame, request: Draft, draft: Draft) -> Draft:
        draft.request_index = request.frame.index
        draft.latency_ns = max(0, frame.t_start_ns - request.frame.t_end_ns)
        request.open = False
        assert request.slave is not None
        del self._open[request.slave]
        if frame.crc_ok:
            self._failed.pop(request.slave, None)
            self._learn(draft.latency_ns)
        else:
            # The master saw no valid answer: its repeat is a retry.
            self._failed[request.slave] = request.frame.data
        return draft

    def _learn(self, latency_ns: int) -> None:
        self._latencies.append(latency_ns)
        if len(self._latencies) % 32 == 0 or len(self._latencies) < 32:
            longest = max(self._latencies)
            self._adaptive_timeout_ns = min(MAX_TIMEOUT_NS, max(MIN_TIMEOUT_NS, TIMEOUT_PER_LATENCY * longest))


def _answers(request: bytes, response: bytes) -> bool:
    """Whether ``response`` (response-shaped, same slave) fits ``request``'s content."""
    if request[1] != response[1] or len(request) < MIN_ADU:
        return False
    function = request[1]
    if function in (1, 2) and len(request) == 8:
        count = request[4] << 8 | request[5]
        return response[2] == (count + 7) // 8
    if function in (3, 4) and len(request) == 8:
        return response[2] == 2 * (request[4] << 8 | request[5])
    if function == 23 and len(request) > 6:
        return response[2] == 2 * (request[4] << 8 | request[5])
    if function in (5, 6, 22, 15, 16):
        return response[2:6] == request[2:6]
    if function == 8:
        return response[2:4] == request[2:4]
    if function == 43:
        return response[2:3] == request[2:3]
    return True
