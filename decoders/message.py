"""Messages: frames with what the decoders found out about them."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

from decoders.frame import Frame, FrameFlag

if TYPE_CHECKING:
    from decoders.modbus.pdu import Pdu


class Role(Enum):
    """What a frame is on the bus; values are the JSONL role names."""

    REQUEST = "request"
    RESPONSE = "response"
    EXCEPTION = "exception"
    #: A request to address 0: every slave executes it, none answers.
    BROADCAST = "broadcast"
    #: Bytes that form no frame.
    NOISE = "noise"
    UNKNOWN = "unknown"


@dataclass(frozen=True, slots=True)
class ParamValue:
    """A register or coil a frame names, with what a device profile knows of it."""

    address: int
    raw: int | None
    code: str | None = None
    name: str | None = None
    value: float | int | str | None = None
    unit: str | None = None


@dataclass(frozen=True, slots=True)
class Message:
    """A frame with its role and decoded meaning.

    ``flags`` holds the framer's flags plus those of later stages (timeouts, retries).
    ``request_index`` and ``latency_ns`` are set on responses and exceptions paired
    with their request; ``pdu``, ``params`` and ``summary`` by the annotator.
    """

    frame: Frame
    role: Role
    slave: int | None
    function: int | None
    exception_code: int | None
    summary: str
    flags: FrameFlag
    request_index: int | None = None
    latency_ns: int | None = None
    params: tuple[ParamValue, ...] = ()
    pdu: Pdu | None = None
