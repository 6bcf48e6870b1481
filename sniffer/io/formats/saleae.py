"""Saleae Logic Async Serial exports, CSV (implementation: :mod:`sniffer.io.saleae_csv`, read only)."""

from __future__ import annotations

from sniffer.io.base import CaptureFormat, CaptureReader, ReaderOptions


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.saleae_csv import SaleaeCsvReader  # noqa: PLC0415 - only when such a file is read

    return SaleaeCsvReader(path, options)


def _sniff(head: bytes) -> bool:
    first = head.removeprefix(b"\xef\xbb\xbf").lstrip()
    return first.startswith((b"name,type,start_time,duration,data", b"Time [s],Value,Parity Error,Framing Error"))


FORMAT = CaptureFormat(
    name="saleae",
    suffixes=(".csv",),
    description="Saleae Logic Async Serial export: Logic 2 data table or Logic 1.x CSV; needs --line",
    sniff=_sniff,
    open_reader=_open_reader,
)
