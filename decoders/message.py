"""Messages: frames with what the decoders found out about them."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from decoders.frame import Frame, FrameBatch, FrameFlag, flag_set, slice_frames

if TYPE_CHECKING:
    from decoders.modbus.pdu import Pdu
    from decoders.uss import UssTelegram


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


# Not frozen (treat as immutable): a frozen dataclass sets each field through object.__setattr__,
# 3× slower to build, and a capture builds one per register it names.
@dataclass(slots=True)
class ParamValue:
    """A register or coil a frame names, with what a device profile knows of it."""

    # In the order of a JSONL param record.
    address: int
    code: str | None = None
    name: str | None = None
    raw: int | None = None
    value: float | int | str | None = None
    unit: str | None = None
    #: False where the raw word is a marker, not a reading (the Altivar's 16#8000 "non-existent
    #: or protected parameter"): ``value`` then says what it means, and no plot takes it.
    available: bool = True
    #: The registers of a value over more than one (a profile's ``f32``), in address order:
    #: ``raw`` is then their bits as one unsigned number in the device's word order.
    words: tuple[int, ...] | None = None

    @property
    def reading(self) -> bool:
        """Whether it carries a reading: a raw value that is not a marker (what plots and
        parameter channels take)."""
        return self.raw is not None and self.available


@dataclass(frozen=True, slots=True)
class DeviceIdentity:
    """What a slave said about itself (FC 43 / MEI 14), and the profile that matches it."""

    slave: int
    vendor: str | None
    product_code: str
    revision: str | None
    profile: str | None
    #: Whether the matching profile now decodes this slave (not when the user chose one).
    applied: bool


# Not frozen, for the same reason as ParamValue: one or two are built per distinct frame.
@dataclass(slots=True, eq=False)
class Decoding:
    """What a frame says, apart from when it was seen: its summary, decoded PDU, params.

    The annotator hands the same object to every message with the same bytes, role,
    protocol and request while the profiles know the same (see
    :class:`decoders.modbus.annotate.Annotator`), so a sink may cache what it derives
    from one by identity (``eq=False``: compared and hashed by identity).
    """

    summary: str
    params: tuple[ParamValue, ...] = ()
    pdu: Pdu | None = None
    #: What the device profile has to say: limits exceeded, exceptions explained.
    remarks: tuple[str, ...] = ()
    device: DeviceIdentity | None = None
    #: The decoded telegram, for frames that are USS rather than Modbus.
    uss: UssTelegram | None = None


#: The decoding of a message no annotator has seen yet.
UNDECODED = Decoding("")
#: The decoding of a message an annotator left in columns (``AnnotatedBatch.columnar``).
IN_COLUMNS = Decoding("(decoded in columns)")


# Not frozen (treat as immutable; only the annotator sets ``decoding`` on messages it has just
# built): a frozen dataclass sets each field through object.__setattr__, and every frame is one.
@dataclass(slots=True)
class Message:
    """A frame with its role and decoded meaning.

    ``flags`` holds the framer's flags plus those of later stages (timeouts, retries).
    ``request_index`` and ``latency_ns`` are set on responses and exceptions paired
    with their request; ``decoding`` by the annotator.
    """

    frame: Frame
    role: Role
    slave: int | None
    function: int | None
    exception_code: int | None
    flags: FrameFlag
    request_index: int | None = None
    latency_ns: int | None = None
    decoding: Decoding = UNDECODED

    @property
    def summary(self) -> str:
        return self.decoding.summary

    @property
    def params(self) -> tuple[ParamValue, ...]:
        return self.decoding.params

    @property
    def pdu(self) -> Pdu | None:
        return self.decoding.pdu

    @property
    def remarks(self) -> tuple[str, ...]:
        return self.decoding.remarks

    @property
    def device(self) -> DeviceIdentity | None:
        return self.decoding.device

    @property
    def uss(self) -> UssTelegram | None:
        return self.decoding.uss


#: Roles by their code in :class:`MessageBatch`.
ROLE_ORDER = [Role.REQUEST, Role.RESPONSE, Role.EXCEPTION, Role.BROADCAST, Role.NOISE, Role.UNKNOWN]
ROLE_CODE = {role: code for code, role in enumerate(ROLE_ORDER)}
#: Each role code's name (``Role.value``, which an enum computes on every read).
ROLE_NAMES = [role.value for role in ROLE_ORDER]
NONE = -1


@dataclass(frozen=True, slots=True)
class MessageBatch:
    """Messages in columns over a :class:`FrameBatch`; ``NONE`` (-1) where a field is empty.

    ``flags`` already holds the frame's flags too.
    """

    frames: FrameBatch
    role: npt.NDArray[np.uint8]
    slave: npt.NDArray[np.int16]
    function: npt.NDArray[np.int16]
    exception_code: npt.NDArray[np.int16]
    flags: npt.NDArray[np.uint16]
    request_index: npt.NDArray[np.int64]
    latency_ns: npt.NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.role)

    def rows(self) -> MessageRows:
        """Messages built on demand by position, from columns read once."""
        return MessageRows(self)

    def __iter__(self) -> Iterator[Message]:
        rows = self.rows()
        return (rows[position] for position in range(len(self)))


class MessageRows:
    """The messages of a batch by position, each built when asked for: for stages that need
    objects for a few messages only (the annotator, for frames it has not seen before)."""

    def __init__(self, batch: MessageBatch) -> None:
        self._batch = batch
        self._frames = batch.frames.rows()
        self._columns: list[list[int]] | None = None

    def __getitem__(self, position: int) -> Message:
        if self._columns is None:
            batch = self._batch
            self._columns = [column.tolist() for column in (batch.role, batch.slave, batch.function,
                                                            batch.exception_code, batch.flags,
                                                            batch.request_index, batch.latency_ns)]
        roles, slaves, functions, codes, flags, requests, latencies = self._columns
        slave, function, code = slaves[position], functions[position], codes[position]
        request, latency = requests[position], latencies[position]
        return Message(
            self._frames[position],
            ROLE_ORDER[roles[position]],
            None if slave == NONE else slave,
            None if function == NONE else function,
            None if code == NONE else code,
            flag_set(flags[position]),
            None if request == NONE else request,
            None if latency == NONE else latency,
        )


def slice_messages(batch: MessageBatch, start: int, stop: int) -> MessageBatch:
    """Messages ``start`` to ``stop`` (positions) of ``batch``, as a batch of their own."""
    return MessageBatch(slice_frames(batch.frames, start, stop), batch.role[start:stop], batch.slave[start:stop],
                        batch.function[start:stop], batch.exception_code[start:stop], batch.flags[start:stop],
                        batch.request_index[start:stop], batch.latency_ns[start:stop])
