"""The registry of capture formats.

Every module in :mod:`sniffer.io.formats` declares one :class:`CaptureFormat` as
``FORMAT``; adding a format is adding a module there (a read-only format leaves
``open_writer`` out). A format is chosen by name, else by the file's suffix, else by
its ``sniff`` of the file's first bytes. Option choices, help texts and error hints
are built from here.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache
from pathlib import Path
from typing import Literal

from decoders.capture import CaptureInfo
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io import formats
from sniffer.io.base import CaptureFormat, CaptureReader, CaptureWriter, ReaderOptions

STDIO = "-"
STDIO_FORMAT = "text"
#: How many leading bytes a format's ``sniff`` sees.
SNIFF_BYTES = 64

Purpose = Literal["read", "write"]


@cache
def all_formats() -> dict[str, CaptureFormat]:
    """Every registered format by name."""
    found: dict[str, CaptureFormat] = {}
    for module_info in pkgutil.iter_modules(formats.__path__):
        module = importlib.import_module(f"{formats.__name__}.{module_info.name}")
        fmt: CaptureFormat = module.FORMAT
        found[fmt.name] = fmt
    return found


def formats_for(purpose: Purpose) -> dict[str, CaptureFormat]:
    """The formats that can be read (``read``) or written (``write``), by name."""
    return {name: fmt for name, fmt in all_formats().items() if _can(fmt, purpose)}


def _can(fmt: CaptureFormat, purpose: Purpose) -> bool:
    return (fmt.open_reader if purpose == "read" else fmt.open_writer) is not None


#: Suffixes that say "text", not which text: the first bytes decide among the formats.
GENERIC_SUFFIXES = frozenset({".txt", ".log", ".csv"})


def find_format(
    path: str, name: str | None = None, head: bytes = b"", *, option: str = "--input-format",
    purpose: Purpose = "read",
) -> CaptureFormat:
    """The format called ``name``, else the one whose suffix ``path`` has, else the one
    whose ``sniff`` recognises ``head`` (the file's first bytes). ``option`` is the
    command's option that names a format, for the error's hint."""
    known = formats_for(purpose)
    if name is not None:
        if name not in known:
            raise RtuSniffError(
                ErrorKind.USAGE, f"unknown capture format {name!r} to {purpose}; known: {', '.join(sorted(known))}"
            )
        return known[name]
    if path == STDIO:
        return known[STDIO_FORMAT]
    suffix = Path(path).suffix.lower()
    by_suffix = next((fmt for fmt in known.values() if suffix in fmt.suffixes), None)
    if by_suffix is not None and suffix not in GENERIC_SUFFIXES:
        return by_suffix
    # A suffix any tool's text may have (sigrok-cli's output saved as .txt, a CSV) decides only
    # while the first bytes are not another format's; no known suffix: the first bytes alone.
    sniffed = [fmt for fmt in known.values() if head and fmt.sniff(head)]
    if by_suffix is not None and (by_suffix in sniffed or not sniffed):
        return by_suffix
    if sniffed:
        return sniffed[0]
    suffixes = ", ".join(s for fmt in known.values() for s in fmt.suffixes)
    raise RtuSniffError(
        ErrorKind.UNKNOWN_FORMAT,
        f"cannot tell the capture format from the suffix {suffix or '(none)'!r}; "
        f"use one of {suffixes}" + (f" or name the format with {option}" if option else ""),
        path=path,
    )


def open_reader(path: str, format_name: str | None = None, options: ReaderOptions | None = None) -> CaptureReader:
    """Open a capture for reading; errors name the file."""
    head = b"" if path == STDIO else _read_head(path)
    fmt = find_format(path, format_name, head)
    assert fmt.open_reader is not None  # formats_for("read") has only readable ones
    if path == STDIO and fmt.name != STDIO_FORMAT:
        raise RtuSniffError(ErrorKind.USAGE, f"standard input carries the {STDIO_FORMAT} format only, not "
                            f"{fmt.name}: give the file's name")
    options = options or ReaderOptions()
    if options.follow and not fmt.followable:
        followable = ", ".join(sorted(name for name, found in formats_for("read").items() if found.followable))
        raise RtuSniffError(ErrorKind.USAGE, f"--follow: a {fmt.name} capture is not written as it grows; follow "
                            f"what 'rtusniff capture -o' records ({followable})", path=path)
    return fmt.open_reader(path, options)


def open_writer(path: str, info: CaptureInfo, format_name: str | None = None) -> CaptureWriter:
    """Create a capture file for writing."""
    fmt = find_format(path, format_name, option="--output-format", purpose="write")
    assert fmt.open_writer is not None  # formats_for("write") has only writable ones
    try:
        return fmt.open_writer(path, info)
    except OSError as exc:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from exc


def format_help(purpose: Purpose) -> str:
    """One line per format that can be read or written: name, suffixes, description."""
    return "; ".join(f"{fmt.name} ({', '.join(fmt.suffixes)}): {fmt.description}"
                     for fmt in sorted(formats_for(purpose).values(), key=lambda f: f.name))


def _read_head(path: str) -> bytes:
    """The first bytes of ``path``, with one-line errors for what cannot be read."""
    target = Path(path)
    if not target.exists():
        raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "no such file", path=path)
    if target.is_dir():
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, "is a directory, not a capture file", path=path)
    try:
        with target.open("rb") as f:
            return f.read(SNIFF_BYTES)
    except OSError as exc:
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from exc
