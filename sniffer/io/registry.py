"""The registry of capture formats.

Every module in :mod:`sniffer.io.formats` declares one :class:`CaptureFormat` as
``FORMAT``; adding a format is adding a module there. Formats are found by name or
by file suffix.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache
from pathlib import Path

from decoders.capture import CaptureInfo
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io import formats
from sniffer.io.base import CaptureFormat, CaptureReader, CaptureWriter

STDIO = "-"
STDIO_FORMAT = "text"
#: How many leading bytes are read to recognise a format by its magic.
MAGIC_LENGTH = 16


@cache
def all_formats() -> dict[str, CaptureFormat]:
    """Every registered format by name."""
    found: dict[str, CaptureFormat] = {}
    for module_info in pkgutil.iter_modules(formats.__path__):
        module = importlib.import_module(f"{formats.__name__}.{module_info.name}")
        fmt: CaptureFormat = module.FORMAT
        found[fmt.name] = fmt
    return found


def find_format(
    path: str, name: str | None = None, head: bytes = b"", *, option: str = "--input-format"
) -> CaptureFormat:
    """The format called ``name``, else the one whose suffix ``path`` has, else the one
    whose magic bytes ``head`` (the file's first bytes) starts with. ``option`` is the
    command's option that names a format, for the error's hint."""
    known = all_formats()
    if name is not None:
        if name not in known:
            raise RtuSniffError(
                ErrorKind.USAGE, f"unknown capture format {name!r}; known: {', '.join(sorted(known))}"
            )
        return known[name]
    if path == STDIO:
        return known[STDIO_FORMAT]
    suffix = Path(path).suffix.lower()
    for fmt in known.values():
        if suffix in fmt.suffixes:
            return fmt
    for fmt in known.values():
        if head.startswith(fmt.magic):
            return fmt
    suffixes = ", ".join(s for fmt in known.values() for s in fmt.suffixes)
    raise RtuSniffError(
        ErrorKind.UNKNOWN_FORMAT,
        f"cannot tell the capture format from the suffix {suffix or '(none)'!r}; "
        f"use one of {suffixes}" + (f" or name the format with {option}" if option else ""),
        path=path,
    )


def open_reader(path: str, format_name: str | None = None) -> CaptureReader:
    """Open a capture for reading; errors name the file."""
    head = b"" if path == STDIO else _read_head(path)
    return find_format(path, format_name, head).open_reader(path)


def open_writer(path: str, info: CaptureInfo, format_name: str | None = None) -> CaptureWriter:
    """Create a capture file for writing."""
    fmt = find_format(path, format_name, option="--output-format")
    try:
        return fmt.open_writer(path, info)
    except OSError as exc:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from exc


def _read_head(path: str) -> bytes:
    """The first bytes of ``path``, with one-line errors for what cannot be read."""
    target = Path(path)
    if not target.exists():
        raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "no such file", path=path)
    if target.is_dir():
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, "is a directory, not a capture file", path=path)
    try:
        with target.open("rb") as f:
            return f.read(MAGIC_LENGTH)
    except OSError as exc:
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from exc
