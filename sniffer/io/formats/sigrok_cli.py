"""sigrok-cli's UART annotations (implementation: :mod:`sniffer.io.sigrok_annotations`, read only)."""

from __future__ import annotations

import re

from sniffer.io.base import CaptureFormat, CaptureReader, ReaderOptions

_FIRST_LINE = re.compile(rb"\s*\d+-\d+ [\w.-]+: [\w-]+: \"")


def _open_reader(path: str, options: ReaderOptions) -> CaptureReader:
    from sniffer.io.sigrok_annotations import SigrokAnnotationsReader  # noqa: PLC0415 - only when read

    return SigrokAnnotationsReader(path, options)


FORMAT = CaptureFormat(
    name="sigrok-cli",
    suffixes=(".ann",),
    description="sigrok-cli's UART annotations (-A uart --protocol-decoder-samplenum, with classes), any suffix: "
    "recognised by the first line; needs --line",
    sniff=lambda head: _FIRST_LINE.match(head) is not None,
    open_reader=_open_reader,
)
