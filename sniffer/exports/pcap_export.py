"""pcap for Wireshark: one packet per frame, already split, with nanosecond times.

Link type 147 (DLT_USER0). Wireshark decodes it as Modbus RTU once User DLT 147 is mapped
to the ``mbrtu`` dissector (Preferences → Protocols → DLT_USER → Encapsulations Table), or
on the command line::

    tshark -o 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""' -r capture.pcap

Noise records are packets too (Wireshark shows them as malformed): nothing is dropped.
"""

from __future__ import annotations

import struct
from typing import BinaryIO

from decoders.message import Message

LINKTYPE_USER0 = 147
_NANOSECOND_MAGIC = 0xA1B23C4D
_HEADER = struct.Struct("<IHHiIII")
_RECORD = struct.Struct("<IIII")
SNAPLEN = 65535
WIRESHARK_USER_DLT = '"User 0 (DLT=147)","mbrtu","0","","0",""'


class PcapExporter:
    def __init__(self, path: str) -> None:
        self._file: BinaryIO = open(path, "wb")  # noqa: SIM115
        self._file.write(_HEADER.pack(_NANOSECOND_MAGIC, 2, 4, 0, 0, SNAPLEN, LINKTYPE_USER0))
        self.packets = 0

    def messages(self, messages: list[Message]) -> None:
        records = []
        for message in messages:
            frame = message.frame
            seconds, nanos = divmod(frame.t_start_ns, 1_000_000_000)
            records.append(_RECORD.pack(seconds, nanos, len(frame.data), len(frame.data)) + frame.data)
        self._file.write(b"".join(records))
        self.packets += len(records)

    def close(self) -> None:
        self._file.close()
