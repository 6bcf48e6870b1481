"""pcap and pcapng files of serial lines, read as captures.

Serial sniffers that feed Wireshark (SerialPCAP, alerighi/modbus-sniffer, extcap serial adapters)
write one record per read or per frame with a user link type (147–162, the bytes as they came)
or RTAC serial (250: a 12-byte header — arrival time, event type, control lines, footer — before
the bytes); rtusniff's own ``export --pcap`` writes link type 147 too. Each record becomes a
chunk at the record's time: ``host`` timing, since a record's time is when software got the
bytes (rtusniff's own export stamps a frame's start: its times read back a frame early, its
frames the same). A pcap does not say the line's settings: ``--line`` gives them. Records out of
time order, other link types and damaged files are one error naming the file and the record.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import BinaryIO

import numpy as np

from decoders.capture import MAX_TIME_NS, CaptureInfo, ChunkBatch, TimingQuality
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io.base import ReaderOptions, max_read_bytes, read_limit_message

USER_LINK_TYPES = range(147, 163)
LINKTYPE_RTAC_SERIAL = 250
#: Raw IPv4: ``export --pcap-link udp`` wraps each frame in a UDP packet.
LINKTYPE_RAW_IP = 101
RTAC_HEADER_BYTES = 12
#: Classic pcap magic numbers (as read little-endian) → (byte order, nanosecond times).
CLASSIC = {0xA1B2C3D4: ("<", False), 0xD4C3B2A1: (">", False), 0xA1B23C4D: ("<", True), 0x4D3CB2A1: (">", True)}
PCAPNG_SECTION = 0x0A0D0D0A
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
_INTERFACE, _ENHANCED, _SIMPLE, _OBSOLETE_PACKET = 1, 6, 3, 2
BATCH_CHUNKS = 4096
NS_PER_S = 1_000_000_000


class PcapCaptureReader:
    """Reads a pcap or pcapng file's records as chunks (see the module docstring)."""

    def __init__(self, path: str, options: ReaderOptions) -> None:
        self.path = path
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        try:
            self._file: BinaryIO = open(path, "rb")  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise CaptureFormatError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from None
        self._record = 0
        try:
            head = self._file.read(12)
            self._pcapng = len(head) >= 4 and struct.unpack("<I", head[:4])[0] == PCAPNG_SECTION
            if self._pcapng and (len(head) < 12 or struct.unpack("<I", head[8:12])[0] not in
                                 (_BYTE_ORDER_MAGIC, 0x4D3C2B1A)):
                raise self._error("not a pcapng (no byte-order magic)", ErrorKind.BAD_HEADER, where="header")
            self._file.seek(0)
            self._records = self._pcapng_records() if self._pcapng else self._classic_records()
            if options.line is None:
                raise self._error("a pcap does not say the line's settings: give --line, e.g. --line 19200 8E1",
                                  ErrorKind.NO_LINE_SETTINGS, where="header")
        except BaseException:
            self._file.close()
            raise
        kind = "pcapng" if self._pcapng else "pcap"
        # pcapng packets may say their direction (epb_flags): kept as the chunk's channel.
        self.info = CaptureInfo(options.line, TimingQuality.HOST, (f"{kind} {path}: a chunk per record, "
                                                                    "at the record's time",),
                                DIRECTIONS if self._pcapng else ())

    def _error(self, message: str, kind: ErrorKind = ErrorKind.BAD_DATA, where: str | None = None
               ) -> CaptureFormatError:
        return CaptureFormatError(kind, message, path=self.path, location=where or f"record {self._record}")

    def _read(self, size: int, what: str) -> bytes:
        data = self._file.read(size)
        if len(data) != size:
            raise self._error(f"cut short in {what} ({len(data)} of {size} bytes)")
        return data

    # Classic pcap.

    def _classic_records(self) -> Iterator[tuple[int, bytes, int]]:
        header = self._read(24, "the file header")
        magic = struct.unpack("<I", header[:4])[0]
        if magic not in CLASSIC:
            raise self._error(f"not a pcap (magic 0x{magic:08X})", ErrorKind.BAD_HEADER, where="header")
        order, nanos = CLASSIC[magic]
        link_type = struct.unpack(order + "I", header[20:24])[0] & 0x0FFFFFFF
        self._check_link_type(link_type, "header")
        record = struct.Struct(order + "IIII")
        scale = 1 if nanos else 1000
        return self._classic_body(record, scale, link_type)

    def _classic_body(self, record: struct.Struct, scale: int, link_type: int) -> Iterator[tuple[int, bytes, int]]:
        while True:
            head = self._file.read(record.size)
            if not head:
                return
            self._record += 1
            if len(head) != record.size:
                raise self._error(f"cut short in a record header ({len(head)} of {record.size} bytes)")
            seconds, fraction, captured, _ = record.unpack(head)
            self._check_size(captured, "record")
            yield seconds * NS_PER_S + fraction * scale, self._payload(self._read(captured, "a record"), link_type), 0

    # pcapng.

    def _pcapng_records(self) -> Iterator[tuple[int, bytes, int]]:
        order = "<"
        interfaces: list[tuple[int, tuple[int, int]]] = []  # per interface: (link type, (base, power) of a tick)

        def blocks() -> Iterator[tuple[int, bytes]]:
            nonlocal order, interfaces
            while True:
                head = self._file.read(8)
                if not head:
                    return
                if len(head) != 8:
                    raise self._error("cut short in a block header")
                kind = struct.unpack("<I", head[:4])[0]
                if kind == PCAPNG_SECTION:
                    magic = self._read(4, "a section header")
                    order = "<" if struct.unpack("<I", magic)[0] == _BYTE_ORDER_MAGIC else ">"
                    length = struct.unpack(order + "I", head[4:])[0]
                    if length < 28 or length % 4:
                        raise self._error(f"section header length {length} is not a pcapng one's")
                    self._check_size(length - 16, "section header")
                    body = magic + self._read(length - 16, "a section header")
                    interfaces = []
                else:
                    kind, length = struct.unpack(order + "II", head)
                    if length < 12 or length % 4:
                        raise self._error(f"block length {length} is not a pcapng block's")
                    self._check_size(length - 12, "block")
                    body = self._read(length - 12, "a block")
                self._read(4, "a block's closing length")
                yield kind, body

        def records() -> Iterator[tuple[int, bytes, int]]:
            for kind, body in blocks():
                if kind == _INTERFACE:
                    link_type = struct.unpack(order + "H", body[:2])[0]
                    interfaces.append((link_type, _resolution(body[8:], order)))
                elif kind == _ENHANCED:
                    self._record += 1
                    if len(body) < 20:
                        raise self._error("an enhanced packet block shorter than its fields")
                    interface, high, low, captured, _ = struct.unpack(order + "IIIII", body[:20])
                    if interface >= len(interfaces):
                        raise self._error(f"names interface {interface}, which no interface block described")
                    link_type, (base, power) = interfaces[interface]
                    self._check_link_type(link_type, f"record {self._record}")
                    channel = _direction(body[20 + (captured + 3) // 4 * 4 :], order)
                    # Exact in integers whatever the resolution (2^-127 s a tick, or 10^0).
                    t_ns = ((high << 32) | low) * NS_PER_S // base**power
                    yield t_ns, self._payload(body[20 : 20 + captured], link_type), channel
                elif kind in (_SIMPLE, _OBSOLETE_PACKET):
                    self._record += 1
                    raise self._error("a packet block without a time (simple or obsolete): not a serial capture's")

        return records()

    def _check_size(self, size: int, what: str) -> None:
        """A record over the read limit is refused before it is read (a length of 4 GiB in a
        small file, or 60 MiB of one record: no serial port delivers either)."""
        if size > max_read_bytes() + 4096:  # room for a block's fields and options
            raise self._error(f"a {what} that {read_limit_message(size)}")

    def _check_link_type(self, link_type: int, where: str) -> None:
        if link_type not in USER_LINK_TYPES and link_type not in (LINKTYPE_RTAC_SERIAL, LINKTYPE_RAW_IP):
            raise self._error(f"link type {link_type} is not a serial line's (rtusniff reads 147-162, user DLT, "
                              "250, RTAC serial, and 101, its own UDP export)", ErrorKind.UNKNOWN_FORMAT, where=where)

    def _payload(self, data: bytes, link_type: int) -> bytes:
        if link_type == LINKTYPE_RAW_IP:
            # IPv4 (its header's length in words) carrying UDP (8 bytes of header): the frame follows.
            if len(data) < 28 or data[0] >> 4 != 4 or data[9] != 17:
                raise self._error("a raw IP record that is not an IPv4 UDP packet")
            return data[(data[0] & 0x0F) * 4 + 8 :]
        if link_type == LINKTYPE_RTAC_SERIAL:
            if len(data) < RTAC_HEADER_BYTES:
                raise self._error(f"an RTAC serial record of {len(data)} bytes, shorter than its header")
            return data[RTAC_HEADER_BYTES:]
        return data

    def batches(self) -> Iterator[ChunkBatch]:
        times: list[int] = []
        parts: list[bytes] = []
        channels: list[int] = []
        previous = -1
        for t_ns, data, channel in self._records:
            if t_ns > MAX_TIME_NS:
                raise self._error(f"a time {t_ns // NS_PER_S:,} s after 1970, beyond the year 2262")
            if t_ns < previous:
                raise self._error("goes back in time from the record before", ErrorKind.DECREASING_TIME)
            previous = t_ns
            if not data:
                continue
            times.append(t_ns)
            parts.append(data)
            channels.append(channel)
            if len(parts) >= BATCH_CHUNKS:
                yield _batch(times, parts, channels)
                times, parts, channels = [], [], []
        if parts:
            yield _batch(times, parts, channels)

    def last_time_ns(self) -> int | None:
        return None

    def close(self) -> None:
        self._file.close()


def _batch(times: list[int], parts: list[bytes], channels: list[int]) -> ChunkBatch:
    lengths = np.fromiter(map(len, parts), np.int64, len(parts))
    said = np.array(channels, np.uint8) if any(channels) else None
    return ChunkBatch(b"".join(parts), np.cumsum(lengths), np.array(times, np.int64), channels=said)


#: The channels of a pcapng capture: its packets' directions (epb_flags bits 0-1: 1, 2).
DIRECTIONS = ("inbound", "outbound")
_EPB_FLAGS = 2


def _direction(options: bytes, order: str) -> int:
    """1 inbound, 2 outbound from an enhanced packet block's ``epb_flags`` option; 0 unsaid."""
    at = 0
    while at + 4 <= len(options):
        code, length = struct.unpack(order + "HH", options[at : at + 4])
        if code == 0:
            break
        if code == _EPB_FLAGS and length == 4 and at + 8 <= len(options):
            return int(struct.unpack(order + "I", options[at + 4 : at + 8])[0] & 0b11) % 3
        at += 4 + (length + 3) // 4 * 4
    return 0


def _resolution(options: bytes, order: str) -> tuple[int, int]:
    """An interface's timestamp tick from its ``if_tsresol`` option, as (base, power): a tick is
    ``base ** -power`` seconds (default: microseconds, (10, 6))."""
    at = 0
    while at + 4 <= len(options):
        code, length = struct.unpack(order + "HH", options[at : at + 4])
        if code == 0:
            break
        if code == 9 and length >= 1 and at + 4 < len(options):  # the option may be cut short
            resolution = options[at + 4]
            return (2 if resolution & 0x80 else 10), resolution & 0x7F
        at += 4 + (length + 3) // 4 * 4
    return 10, 6
