"""Writing the rtu-capture text format v1 (docs/capture-text-format.md); the reader is
:mod:`sniffer.io.formats.text`, and both take the format's fixed text from here."""

from __future__ import annotations

import contextlib
import os
import re
import sys
from typing import TextIO

from decoders.capture import CaptureInfo, ChunkBatch, uart_error_name
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



NOTE_MARK = "(note) "
_DIRECTIVE = re.compile(r"\s*(rtu-capture|line|timing|channels?|uart-errors)\b", re.IGNORECASE)


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


class TextCaptureWriter:
    """Writes the header at once, then one line per chunk."""

    def __init__(self, path: str, info: CaptureInfo) -> None:
        self._stream: TextIO = sys.stdout if path == STDIO else open_new_text(path, encoding="ascii")
        header = [MAGIC]
        if info.line is not None:
            header.append(f"# line: {info.line.format()}")
        header.append(f"# timing: {info.timing.value}")
        if info.channels:
            header.append(f"# channels: {' '.join(info.channels)}")
        header.extend(line for note in info.notes for line in comment_lines(note))
        self._stream.write("\n".join(header) + "\n")
        self.flush()  # on disk at once: a capture killed before its first line still says what it is
        self._channels = info.channels
        self._channel = 0

    def write_batch(self, batch: ChunkBatch) -> None:
        lines = []
        for chunk in batch.chunks():
            if not chunk.data:
                raise ValueError("the text format cannot hold a chunk without bytes")
            if chunk.channel != self._channel:
                self._channel = chunk.channel
                name = self._channels[chunk.channel - 1] if 0 < chunk.channel <= len(self._channels) else NO_CHANNEL
                lines.append(f"# channel: {name}\n")
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
