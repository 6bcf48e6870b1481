"""pcap for Wireshark: one packet per frame, already split, with nanosecond times.

Each frame in an IPv4/UDP packet (link type 101, :func:`udp_packets`), by default: Wireshark's
Modbus RTU dissector then tells every query from its response by the ports, once UDP port 502 is
Modbus RTU (the profile ``rtusniff wireshark setup`` writes: ``wireshark -C rtusniff FILE``).
``udp=False``: the frames alone, link type 147 (DLT_USER0), which Wireshark reads once User DLT
147 is mapped to ``mbrtu`` (the same profile maps it), but cannot classify FC 6, 8, 23 and 43.

Noise records are packets too (Wireshark shows them as data): nothing is dropped.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Sequence
from dataclasses import replace
from typing import BinaryIO

import numpy as np

from decoders.capture import MAX_TIME_NS
from decoders.damage import uart_error_note
from decoders.frame import MODBUS, FrameBatch, FrameFlag, flag_set
from decoders.message import NONE, ROLE_CODE, ROLE_NAMES, MessageBatch, Role
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.output_files import open_new

LINKTYPE_USER0 = 147
_NANOSECOND_MAGIC = 0xA1B23C4D
_HEADER = struct.Struct("<IHHiIII")
#: Per packet: seconds, nanoseconds, captured length, original length.
_RECORD = np.dtype([("seconds", "<u4"), ("nanos", "<u4"), ("captured", "<u4"), ("length", "<u4")])
SNAPLEN = 65535
WIRESHARK_USER_DLT = '"User 0 (DLT=147)","mbrtu","0","","0",""'


class PcapExporter:
    """Writes frames as they are framed: it needs no decoding, so it takes whole batches.
    A path ending in ``.pcapng`` gets pcapng, with each packet's direction and a comment."""

    def __init__(self, path: str, *, udp: bool = True, pcapng: bool | None = None) -> None:
        """``path`` ``-``: standard output (``| wireshark -k -i -``), classic pcap. ``udp``: each
        frame in an IPv4/UDP packet (:func:`udp_packets`) instead of link type 147. ``pcapng``:
        whether to write pcapng (``None``: if the name ends in ``.pcapng``)."""
        self._to_stdout = path == "-"
        self._pcapng = path.lower().endswith(".pcapng") if pcapng is None else pcapng
        self._udp = udp
        link = LINKTYPE_RAW_IP if udp else LINKTYPE_USER0
        self._file: BinaryIO = sys.stdout.buffer if self._to_stdout else open_new(path)
        if self._pcapng:
            self._file.write(pcapng_header(link))
        else:
            self._file.write(_HEADER.pack(_NANOSECOND_MAGIC, 2, 4, 0, 0, SNAPLEN, link))

    @property
    def comments(self) -> bool:
        """Whether its packets carry comments (pcapng), which say each frame's summary."""
        return self._pcapng

    def batch(self, batch: MessageBatch, summaries: Sequence[str] | None = None) -> None:
        """Every frame of ``batch`` (``summaries``: their summary lines, for the comments)."""
        if self._udp:
            batch = udp_packets(batch)
        self._file.write(pcapng_blocks(batch, summaries) if self._pcapng else pcap_records(batch))
        self._file.flush()  # a reader of a pipe (Wireshark live) sees each batch as it is framed

    def close(self) -> None:
        if self._to_stdout:
            self._file.flush()
        else:
            self._file.close()


#: The last moment a classic pcap's unsigned 32-bit seconds hold.
CLASSIC_LAST_NS = (2**32) * 1_000_000_000 - 1


def _refuse_outside(frames: FrameBatch, last_ns: int, holds: str) -> None:
    """One error for the first frame whose start is before 1970 or after ``last_ns``: the formats'
    times are unsigned, and numpy or struct would wrap them without a word."""
    outside = (frames.t_start_ns < 0) | (frames.t_start_ns > last_ns)
    if len(frames) and outside.any():
        first = int(np.argmax(outside))
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"frame #{frames.first_index + first} starts "
                            f"{int(frames.t_start_ns[first]) / 1e9:,.6f} s from 1970, outside what {holds}")


def pcap_records(batch: MessageBatch) -> bytes:
    """Every frame of ``batch`` as a pcap record (header, then its bytes), built in columns."""
    frames = batch.frames
    count = len(frames)
    lengths = np.diff(frames.offsets)
    headers = np.empty(count, _RECORD)
    _refuse_outside(frames, CLASSIC_LAST_NS, "a classic pcap's 32-bit seconds hold (1970 to 2106): write .pcapng, "
                    "whose times have 64 bits")
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


# pcapng: a section, one interface (nanosecond times), an enhanced packet block per frame.
_SHB, _IDB, _EPB = 0x0A0D0D0A, 1, 6
_OPT_COMMENT, _EPB_FLAGS, _SHB_USERAPPL, _IF_TSRESOL = 1, 2, 4, 9
#: epb_flags direction bits (pcapng): as the master sees the line.
INBOUND, OUTBOUND = 1, 2
_DIRECTIONS = {ROLE_CODE[Role.REQUEST]: OUTBOUND, ROLE_CODE[Role.BROADCAST]: OUTBOUND,
               ROLE_CODE[Role.RESPONSE]: INBOUND, ROLE_CODE[Role.EXCEPTION]: INBOUND}


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + value + bytes(-len(value) % 4)


def _block(kind: int, body: bytes) -> bytes:
    length = 12 + len(body)
    return struct.pack("<II", kind, length) + body + struct.pack("<I", length)


def pcapng_header(link_type: int = LINKTYPE_USER0) -> bytes:
    """The section header (written by rtusniff) and the one interface: its link type,
    nanosecond timestamps."""
    section = struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1) + _option(_SHB_USERAPPL, b"rtusniff") + _option(0, b"")
    interface = struct.pack("<HHI", link_type, 0, SNAPLEN) + _option(_IF_TSRESOL, b"\x09") + _option(0, b"")
    return _block(_SHB, section) + _block(_IDB, interface)


def pcapng_blocks(batch: MessageBatch, summaries: Sequence[str] | None = None) -> bytes:
    """An enhanced packet block per frame: its bytes at its start time, its direction (a request
    goes out from the master, an answer comes in) and a comment saying what rtusniff made of it
    (after `` — ``, each frame's summary line where ``summaries`` gives them: the values a profile
    names, which Wireshark does not know)."""
    frames = batch.frames
    _refuse_outside(frames, MAX_TIME_NS, "a pcapng's unsigned times hold (from 1970)")
    blocks = []
    data, offsets, frame_rows = frames.data, frames.offsets.tolist(), frames.rows()
    columns = zip(frames.t_start_ns.tolist(), batch.role.tolist(), batch.request_index.tolist(),
                  batch.latency_ns.tolist(), batch.flags.tolist(), strict=True)
    for position, (t_ns, role, request, latency, flags) in enumerate(columns):
        payload = data[offsets[position] : offsets[position + 1]]
        comment = f"rtusniff #{frames.first_index + position}: {ROLE_NAMES[role]}"
        if request != NONE:
            comment += f" to #{request}" + (f", latency {latency / 1e6:.3f} ms" if latency != NONE else "")
        if flags:
            comment += ", " + ", ".join(flag_set(flags).names)
        if flags & FrameFlag.UART_ERROR:
            comment += f"; {uart_error_note(frame_rows[position].uart_errors)}"
        if summaries is not None:
            comment += f" — {summaries[position]}"
        body = struct.pack("<IIIII", 0, t_ns >> 32, t_ns & 0xFFFFFFFF, len(payload), len(payload))
        body += payload + bytes(-len(payload) % 4)
        body += _option(_EPB_FLAGS, struct.pack("<I", _DIRECTIONS.get(role, 0))) + \
            _option(_OPT_COMMENT, comment.encode()) + _option(0, b"")
        blocks.append(_block(_EPB, body))
    return b"".join(blocks)


#: Raw IPv4 packets: the ``udp`` link.
LINKTYPE_RAW_IP = 101
MODBUS_PORT, MASTER_PORT, NOISE_PORT, OTHER_PROTOCOL_PORT = 502, 40000, 40001, 40002
#: The master, and slave N as 198.19.0.N (RFC 2544's benchmarking range: never a real host).
MASTER_ADDRESS = bytes([198, 18, 0, 1])


def udp_packets(batch: MessageBatch) -> MessageBatch:
    """The batch with each frame wrapped in an IPv4/UDP packet: a request (or broadcast) from
    the master's port 40000 to its slave's port 502, an answer back, noise from port 40001 and
    other protocols' frames (USS) from port 40002 (not Modbus: Wireshark shows their bytes as
    data). Wireshark's Modbus RTU over UDP then knows a query from a response by the ports, for
    every function code."""
    frames = batch.frames
    packets = []
    offsets, data = frames.offsets.tolist(), frames.data
    columns = zip(batch.role.tolist(), batch.slave.tolist(), frames.protocols().tolist(), strict=True)
    for position, (role, slave, protocol) in enumerate(columns):
        payload = data[offsets[position] : offsets[position + 1]]
        slave_address = bytes([198, 19, 0, max(slave, 0)])
        if role == ROLE_CODE[Role.NOISE] or protocol != MODBUS:
            # Not Modbus (noise, a USS telegram): not to port 502, where Wireshark would read it as Modbus.
            port = NOISE_PORT if role == ROLE_CODE[Role.NOISE] else OTHER_PROTOCOL_PORT
            packets.append(_udp(MASTER_ADDRESS, MASTER_ADDRESS, port, port, payload))
        elif role in (ROLE_CODE[Role.RESPONSE], ROLE_CODE[Role.EXCEPTION]):
            packets.append(_udp(slave_address, MASTER_ADDRESS, MODBUS_PORT, MASTER_PORT, payload))
        else:
            packets.append(_udp(MASTER_ADDRESS, slave_address, MASTER_PORT, MODBUS_PORT, payload))
    lengths = np.fromiter(map(len, packets), np.int64, len(packets))
    offsets_out = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    return replace(batch, frames=replace(frames, data=b"".join(packets), offsets=offsets_out))


def _udp(source: bytes, destination: bytes, source_port: int, destination_port: int, payload: bytes) -> bytes:
    udp = struct.pack("!HHHH", source_port, destination_port, 8 + len(payload), 0) + payload
    header = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, 17, 0, source, destination)
    words = sum(struct.unpack("!10H", header))
    words = (words >> 16) + (words & 0xFFFF)
    checksum = ~(words + (words >> 16)) & 0xFFFF
    return header[:10] + struct.pack("!H", checksum) + header[12:] + udp
