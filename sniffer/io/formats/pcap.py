"""pcap and pcapng files of serial lines (implementation: :mod:`sniffer.io.pcap_reader`, read
only; ``export --pcap`` writes them)."""

from __future__ import annotations

import struct

from sniffer.io.base import CaptureFormat, CaptureReader, ReaderOptions


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.pcap_reader import PcapCaptureReader  # noqa: PLC0415 - only when a pcap is read

    return PcapCaptureReader(path, options)


def _sniff(head: bytes) -> bool:
    from sniffer.io.pcap_reader import CLASSIC, PCAPNG_SECTION  # noqa: PLC0415 - light, as above

    return len(head) >= 4 and struct.unpack("<I", head[:4])[0] in (*CLASSIC, PCAPNG_SECTION)


FORMAT = CaptureFormat(
    name="pcap",
    suffixes=(".pcap", ".pcapng"),
    description="pcap/pcapng of a serial line: link type 147-162 (user DLT) or 250 (RTAC serial); needs --line",
    sniff=_sniff,
    open_reader=_open_reader,
)
