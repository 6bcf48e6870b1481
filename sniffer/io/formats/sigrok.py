"""sigrok / PulseView sessions (implementation: :mod:`sniffer.io.sigrok_session`, read only)."""

from __future__ import annotations

from sniffer.io.base import CaptureFormat, CaptureReader, ReaderOptions

ZIP_MAGIC = b"PK\x03\x04"


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.sigrok_session import SigrokSessionReader  # noqa: PLC0415 - numpy and zipfile only when used

    return SigrokSessionReader(path, options)


def _sniff(head: bytes) -> bool:
    """A zip whose first member is a sigrok session's ``version`` or ``metadata``."""
    return head.startswith(ZIP_MAGIC) and (b"version" in head[:64] or b"metadata" in head[:64])


FORMAT = CaptureFormat(
    name="sigrok",
    suffixes=(".sr",),
    description="sigrok/PulseView session: logic samples, decoded as UART (--line, --channel)",
    sniff=_sniff,
    open_reader=_open_reader,
)
