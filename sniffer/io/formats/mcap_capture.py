"""The native MCAP capture (implementation: :mod:`sniffer.io.mcap_native`, imported when used)."""

from __future__ import annotations

from decoders.capture import CaptureInfo
from sniffer.io.base import CaptureFormat, CaptureReader, CaptureWriter, ReaderOptions

MAGIC = b"\x89MCAP"


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.mcap_native import McapCaptureReader  # noqa: PLC0415 - mcap and zstandard only when used

    return McapCaptureReader(path, follow=options.follow, line_given=options.line is not None)


def _open_writer(path: str, info: CaptureInfo) -> CaptureWriter:
    from sniffer.io.mcap_native import McapCaptureWriter  # noqa: PLC0415 - mcap and zstandard only when used

    return McapCaptureWriter(path, info)


FORMAT = CaptureFormat(
    name="mcap",
    suffixes=(".mcap",),
    description="MCAP with raw chunks in blocks and line settings as metadata (native, fast)",
    sniff=lambda head: head.startswith(MAGIC),
    open_reader=_open_reader,
    open_writer=_open_writer,
    followable=True,
)
