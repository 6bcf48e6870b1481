"""The PDUs of Modbus's serial-line diagnostics, files, FIFOs and device identification (FC 7,
8, 11, 12, 17, 20, 21, 24, 43): their dataclasses, each with its one-line ``summary``. The PDUs
of reading and writing data are in :mod:`decoders.modbus.pdu`, which holds the union of all.
"""

from __future__ import annotations

from dataclasses import dataclass

from decoders.modbus.codes import (
    MEI_NAMES,
    READ_DEVICE_ID_CODES,
    device_id_object_name,
    diagnostic_name,
    function_name,
)
from decoders.modbus.pdu_text import hex_words


# Not frozen, hashed by value: see the note above the classes of decoders.modbus.pdu.
@dataclass(slots=True, unsafe_hash=True)
class NoData:
    """A request without data (FC 7, 11, 12, 17)."""

    function: int

    def summary(self) -> str:
        return function_name(self.function).lower()


@dataclass(slots=True, unsafe_hash=True)
class ExceptionStatus:
    """FC 7 response."""

    status: int

    def summary(self) -> str:
        return f"exception status = {self.status:08b}"


@dataclass(slots=True, unsafe_hash=True)
class Diagnostics:
    """FC 8, request or response: a sub-function and its data."""

    sub_function: int
    data: bytes

    @property
    def name(self) -> str:
        return diagnostic_name(self.sub_function)

    def summary(self) -> str:
        shown = self.data.hex(" ").upper() if self.data else "none"
        return f"diagnostics {self.sub_function:02X} {self.name}, data {shown}"


@dataclass(slots=True, unsafe_hash=True)
class CommEventCounter:
    """FC 11 response."""

    status: int
    event_count: int

    def summary(self) -> str:
        busy = "busy" if self.status == 0xFFFF else "ready"
        return f"comm event counter = {self.event_count} ({busy})"


@dataclass(slots=True, unsafe_hash=True)
class CommEventLog:
    """FC 12 response."""

    status: int
    event_count: int
    message_count: int
    events: bytes

    def summary(self) -> str:
        return f"comm events {self.event_count}, messages {self.message_count}, log {self.events.hex(' ').upper()}"


@dataclass(slots=True, unsafe_hash=True)
class ServerId:
    """FC 17 response: device-specific id bytes, the run indicator last."""

    data: bytes

    def summary(self) -> str:
        run = {0x00: "OFF", 0xFF: "ON"}.get(self.data[-1], "?") if self.data else "?"
        return f"server id {self.data[:-1].hex(' ').upper() or '-'}, run indicator {run}"


@dataclass(slots=True, unsafe_hash=True)
class FileSubRequest:
    reference_type: int
    file: int
    record: int
    length: int
    data: tuple[int, ...] = ()


@dataclass(slots=True, unsafe_hash=True)
class FileRecords:
    """FC 20 and 21, request and response: a list of file sub-requests or records."""

    function: int
    items: tuple[FileSubRequest, ...]

    def summary(self) -> str:
        verb = "read" if self.function == 20 else "write"
        parts = [f"file {i.file} rec {i.record} len {i.length}" for i in self.items[:4]]
        return f"{verb} file records: {'; '.join(parts) or 'none'}"


@dataclass(slots=True, unsafe_hash=True)
class FileReadResponse:
    """FC 20 response: one group of register words per sub-request."""

    groups: tuple[tuple[int, ...], ...]

    def summary(self) -> str:
        return "file records = " + "; ".join(hex_words(g, 4) for g in self.groups[:4])


@dataclass(slots=True, unsafe_hash=True)
class FifoRequest:
    """FC 24 request."""

    address: int

    def summary(self) -> str:
        return f"read FIFO at HR {self.address}"


@dataclass(slots=True, unsafe_hash=True)
class FifoResponse:
    """FC 24 response."""

    values: tuple[int, ...]

    def summary(self) -> str:
        return f"FIFO = {hex_words(self.values)} ({len(self.values)} entries)"


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdRequest:
    """FC 43 / MEI 14 request."""

    read_code: int
    object_id: int

    def summary(self) -> str:
        kind = READ_DEVICE_ID_CODES.get(self.read_code, f"code {self.read_code}")
        return f"read device identification ({kind}) from object {self.object_id}"


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdObject:
    object_id: int
    value: bytes

    @property
    def name(self) -> str:
        return device_id_object_name(self.object_id)

    @property
    def text(self) -> str:
        return self.value.decode("latin-1")


@dataclass(slots=True, unsafe_hash=True)
class DeviceIdResponse:
    """FC 43 / MEI 14 response."""

    read_code: int
    conformity: int
    more_follows: bool
    next_object_id: int
    objects: tuple[DeviceIdObject, ...]

    def summary(self) -> str:
        shown = ", ".join(f"{o.name}={o.text!r}" for o in self.objects)
        more = f", more follows from object {self.next_object_id}" if self.more_follows else ""
        return f"device identification: {shown}{more}"


@dataclass(slots=True, unsafe_hash=True)
class MeiRaw:
    """FC 43 with an MEI type other than 14 (e.g. 13, CANopen general reference)."""

    mei_type: int
    data: bytes

    def summary(self) -> str:
        name = MEI_NAMES.get(self.mei_type, f"MEI type {self.mei_type}")
        return f"{name}: {self.data.hex(' ').upper() or 'no data'}"
