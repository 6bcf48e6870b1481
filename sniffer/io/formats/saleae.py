"""Saleae Logic Async Serial exports, CSV (implementation: :mod:`sniffer.io.saleae_csv`, read only)."""

from __future__ import annotations

from sniffer.io.base import CaptureFormat, CaptureReader, ReaderOptions


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.saleae_csv import open_saleae  # noqa: PLC0415 - only when such a file is read

    return open_saleae(path, options)


def _sniff(head: bytes) -> bool:
    first = head.removeprefix(b"\xef\xbb\xbf").lstrip()
    return first.startswith((b"name,type,start_time,duration,data", b"Time [s],"))


FORMAT = CaptureFormat(
    name="saleae",
    suffixes=(".csv",),
    description="Saleae Logic export: Async Serial (Logic 2 data table, Logic 1.x CSV) or raw digital (decoded "
    "as UART); needs --line",
    sniff=_sniff,
    open_reader=_open_reader,
)
