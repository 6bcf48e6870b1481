"""Writing the rtu-capture text format v1 (docs/capture-text-format.md); the reader is
:mod:`sniffer.io.formats.text`, and both take the format's fixed text from here."""

from __future__ import annotations

import contextlib
import os
import re
import sys
from typing import TextIO

from decoders.capture import CaptureInfo, ChunkBatch, uart_error_name
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.output_files import open_new_text
from sniffer.io.registry import STDIO

MAGIC = "# rtu-capture v1"
#: ``# channel: -``: the following lines' channel is not said.
NO_CHANNEL = "-"
UART_ERRORS_PREFIX = "# uart-errors: "
NS_PER_S = 1_000_000_000


def format_time_ns(t_ns: int) -> str:
    """Seconds since the epoch with all nine fractional digits."""
    seconds, nanos = divmod(t_ns, NS_PER_S)
    return f"{seconds}.{nanos:09d}"


#: The characters a channel name keeps as they are in the text format; every other one (a
#: space, ``%``, ``#``, a control or non-ASCII character) is written as ``%XX`` per UTF-8 byte.
_NAME_KEPT = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_.-+:()[]/@=,;~!*'&$")
#: The token of the empty name (a lone ``%`` is no escape).
EMPTY_NAME = "%"


def channel_token(name: str) -> str:
    """A channel name as one token of ``# channels:`` and ``# channel:``: a name from any reader
    (a newline in a probe name, a space in Saleae's ``Channel 0``, ``Empfänger``) round-trips
    and never becomes a line of its own."""
    if not name:
        return EMPTY_NAME
    if name == NO_CHANNEL:
        return "%2D"
    return "".join(char if char in _NAME_KEPT else "".join(f"%{byte:02X}" for byte in char.encode("utf-8",
                                                                                               "surrogatepass"))
                   for char in name)


def channel_name(token: str) -> str:
    """The name a token stands for; ``ValueError`` for a ``%`` not followed by two hex digits or
    bytes that are not UTF-8 (a name without ``%`` is itself, as plain v1 files write it)."""
    if token == EMPTY_NAME:
        return ""
    if "%" not in token:
        return token
    parts = token.split("%")
    data = bytearray(parts[0].encode("ascii", "surrogateescape"))
    for part in parts[1:]:
        if len(part) < 2 or any(c not in "0123456789abcdefABCDEF" for c in part[:2]):
            raise ValueError(f"'%{part[:2]}' is not an escape (%XX, two hex digits)")
        data.append(int(part[:2], 16))
        data.extend(part[2:].encode("ascii", "surrogateescape"))
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"escaped bytes are not UTF-8 ({error.reason})") from None


NOTE_MARK = "(note) "
_DIRECTIVE = re.compile(r"\s*(rtu-capture|line|timing|channels?|uart-errors|heard-until)\b", re.IGNORECASE)
#: ``# heard-until: TIME``: a chunk without bytes, the line heard (quiet) until then.
HEARD_UNTIL_PREFIX = "# heard-until: "


def comment_lines(note: str) -> list[str]:
    """A capture note as comment lines a reader keeps as notes: one per line of the note (a
    newline must not start a data line), outside ASCII as ``\\xe9``-style escapes (the format
    is ASCII), and a line that would read as a header or extension line marked ``(note)``."""
    lines = []
    for line in note.splitlines() or [""]:
        ascii_text = line.encode("ascii", "backslashreplace").decode("ascii")
        text = "".join(char if char.isprintable() else f"\\x{ord(char):02x}" for char in ascii_text)
        lines.append(f"# {NOTE_MARK if _DIRECTIVE.match(text) else ''}{text}" if text else "#")
    return lines


def _refuse_repeated(path: str, names: tuple[str, ...]) -> None:
    """The text format says a line by its name: two lines of one name cannot be told apart."""
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"two of the capture's lines are named {name!r}, which the "
                                "text format cannot tell apart (write .mcap, which keeps them apart)", path=path)
        seen.add(name)


class TextCaptureWriter:
    """Writes the header at once, then one line per chunk."""

    def __init__(self, path: str, info: CaptureInfo) -> None:
        _refuse_repeated(path, info.channels)
        self._stream: TextIO = sys.stdout if path == STDIO else open_new_text(path, encoding="ascii")
        header = [MAGIC]
        if info.line is not None:
            header.append(f"# line: {info.line.format()}")
        header.append(f"# timing: {info.timing.value}")
        if info.first_index:
            header.append(f"# first-frame: {info.first_index}")
        if info.channels:
            header.append(f"# channels: {' '.join(map(channel_token, info.channels))}")
        header.extend(line for note in info.notes for line in comment_lines(note))
        self._stream.write("\n".join(header) + "\n")
        self.flush()  # on disk at once: a capture killed before its first line still says what it is
        self._channels = info.channels
        self._channel = 0

    def write_batch(self, batch: ChunkBatch) -> None:
        lines = []
        for chunk in batch.chunks():
            if not chunk.data:  # no data line: the line heard until then (a live capture's recording ends so)
                lines.append(f"{HEARD_UNTIL_PREFIX}{format_time_ns(chunk.t_end_ns)}\n")
                continue
            if chunk.channel != self._channel:
                self._channel = chunk.channel
                known = 0 < chunk.channel <= len(self._channels)
                token = channel_token(self._channels[chunk.channel - 1]) if known else NO_CHANNEL
                lines.append(f"# channel: {token}\n")
            lines.append(f"{format_time_ns(chunk.t_end_ns)} {chunk.data.hex(' ').upper()}\n")
            if chunk.uart_errors:
                marks = ", ".join(f"{position} {uart_error_name(kind)}" for position, kind in chunk.uart_errors)
                lines.append(f"{UART_ERRORS_PREFIX}{marks}\n")
        self._stream.write("".join(lines))

    def add_notes(self, notes: list[str]) -> None:
        self._stream.write("".join(f"{line}\n" for note in notes for line in comment_lines(note)))

    def flush(self) -> None:
        self._stream.flush()
        if self._stream is not sys.stdout:
            os.fsync(self._stream.fileno())

    @property
    def size(self) -> int:
        """Bytes written so far."""
        return self._stream.tell() if self._stream is not sys.stdout else 0

    def close(self) -> None:
        self.flush()
        if self._stream is not sys.stdout:
            self._stream.close()

    def abandon(self) -> None:
        with contextlib.suppress(OSError):
            self._stream.close()
