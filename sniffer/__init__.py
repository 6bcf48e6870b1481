"""rtusniff: a Modbus RTU protocol analyzer and passive RS485 bus sniffer.

The command line is :mod:`sniffer.cli`; as a library, :func:`open_capture` (``docs/api.md``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from sniffer.errors import ErrorKind, RtuSniffError
    from sniffer.exports import TABLES
    from sniffer.library import Capture, open_capture

__all__ = ["TABLES", "Capture", "ErrorKind", "RtuSniffError", "open_capture"]


def __getattr__(name: str) -> Any:
    """The library's names, imported when first used: the command line's start imports none of it."""
    if name in ("ErrorKind", "RtuSniffError"):
        from sniffer import errors  # noqa: PLC0415

        return getattr(errors, name)
    if name == "TABLES":
        from sniffer import exports  # noqa: PLC0415

        return exports.TABLES
    if name in ("Capture", "open_capture"):
        from sniffer import library  # noqa: PLC0415

        return getattr(library, name)
    raise AttributeError(f"module 'sniffer' has no attribute {name!r}")
