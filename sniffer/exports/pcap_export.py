"""pcap for Wireshark: one packet per frame, already split, with nanosecond times.

Link type 147 (DLT_USER0). Wireshark decodes it as Modbus RTU once User DLT 147 is mapped
to the ``mbrtu`` dissector (Preferences → Protocols → DLT_USER → Encapsulations Table), or
on the command line::

    tshark -o 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""' -r capture.pcap

Noise records are packets too (Wireshark shows them as malformed): nothing is dropped.
"""

from __future__ import annotations

import struct
import sys
from typing import BinaryIO

import numpy as np

from decoders.message import MessageBatch

LINKTYPE_USER0 = 147
_NANOSECOND_MAGIC = 0xA1B23C4D
_HEADER = struct.Struct("<IHHiIII")
#: Per packet: seconds, nanoseconds, captured length, original length.
_RECORD = np.dtype([("seconds", "<u4"), ("nanos", "<u4"), ("captured", "<u4"), ("length", "<u4")])
SNAPLEN = 65535
WIRESHARK_USER_DLT = '"User 0 (DLT=147)","mbrtu","0","","0",""'


class PcapExporter:
    """Writes frames as they are framed: it needs no decoding, so it takes whole batches."""

    def __init__(self, path: str) -> None:
        """``path`` ``-``: standard output (``| wireshark -k -i -``)."""
        self._to_stdout = path == "-"
        self._file: BinaryIO = sys.stdout.buffer if self._to_stdout else open(path, "wb")  # noqa: SIM115
        self._file.write(_HEADER.pack(_NANOSECOND_MAGIC, 2, 4, 0, 0, SNAPLEN, LINKTYPE_USER0))

    def batch(self, batch: MessageBatch) -> None:
        self._file.write(pcap_records(batch))

    def close(self) -> None:
        if self._to_stdout:
            self._file.flush()
        else:
            self._file.close()


def pcap_records(batch: MessageBatch) -> bytes:
    """Every frame of ``batch`` as a pcap record (header, then its bytes), built in columns."""
    frames = batch.frames
    count = len(frames)
    lengths = np.diff(frames.offsets)
    headers = np.empty(count, _RECORD)
    headers["seconds"], headers["nanos"] = np.divmod(frames.t_start_ns, 1_000_000_000)
    headers["captured"] = headers["length"] = lengths
    out = np.empty(count * _RECORD.itemsize + len(frames.data), np.uint8)
    # Record i starts after i headers and the bytes of the frames before it.
    starts = frames.offsets[:-1] + _RECORD.itemsize * np.arange(count)
    header_bytes = headers.view(np.uint8).reshape(count, _RECORD.itemsize)
    out[(starts[:, None] + np.arange(_RECORD.itemsize)).ravel()] = header_bytes.ravel()
    data_positions = np.arange(len(frames.data)) + _RECORD.itemsize * np.repeat(np.arange(1, count + 1), lengths)
    out[data_positions] = np.frombuffer(frames.data, np.uint8)
    return out.tobytes()
