"""The rtu-capture text format v1 (docs/capture-text-format.md), read and write.

```
# rtu-capture v1
# line: 19200 8E1
# timing: exact
1700000000.011173964 02 03 0C 1E 00 04 27 6C
```
A data line with characters the receiver found wrong is followed by a comment naming them
(``# uart-errors: 3 framing, 7 parity``: 0-based byte positions in that line); a capture of
several lines names them in its header (``# channels: RX TX``) and says before a data line
which one the following lines came from (``# channel: TX``). A reader of plain v1 keeps these
comments as notes and reads every byte as before.
The reader stops at the first error and names the file, the line and the fault.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from typing import BinaryIO, cast

import numpy as np

from decoders.capture import MAX_TIME_NS, UART_ERROR_KINDS, CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import CaptureFormatError, ErrorKind, shown
from sniffer.io.base import CaptureFormat, max_read_bytes, read_limit_message
from sniffer.io.following import GrowingFile
from sniffer.io.registry import STDIO
from sniffer.io.text_writer import MAGIC, NO_CHANNEL, NS_PER_S, TextCaptureWriter, channel_name, format_time_ns

_MAGIC_ANY_VERSION = re.compile(r"#\s*rtu-capture\s+v(\S+)")
#: Seconds of up to 19 digits (more cannot be a time: 2^63 ns is 9 223 372 036 s).
_TIME = re.compile(r"[0-9]{1,19}(?:\.[0-9]{1,9})?")
_HEADER_KEY = re.compile(r"#\s*(line|timing|first-frame)\s*:\s*(.*)$", re.IGNORECASE)
_UART_ERRORS = re.compile(r"#\s*uart-errors\s*:\s*(.*)$", re.IGNORECASE)
_CHANNELS = re.compile(r"#\s*channels\s*:\s*(.*)$", re.IGNORECASE)
_CHANNEL = re.compile(r"#\s*channel\s*:\s*(\S+)\s*$", re.IGNORECASE)
_HEARD_UNTIL = re.compile(r"#\s*heard-until\s*:\s*(\S+)\s*$", re.IGNORECASE)
_UART_MARK = re.compile(r"(\d+)\s+(framing\+parity|framing|parity)", re.IGNORECASE | re.ASCII)
#: Bytes read from the end of a file to find its last time (progress).
TAIL_BYTES = 65536
#: Chunks per batch handed to the framer.
BATCH_CHUNKS = 8192
#: Comment lines kept as notes at most, and the bytes they may hold (the rest are counted).
MAX_NOTES = 1000
MAX_NOTE_BYTES = 2**20


def parse_time_ns(text: str) -> int | None:
    """Integer nanoseconds from ``SECONDS[.FRACTION]``; ``None`` if malformed."""
    if _TIME.fullmatch(text) is None:
        return None
    seconds, _, fraction = text.partition(".")
    return int(seconds) * NS_PER_S + int(fraction.ljust(9, "0") or 0)


@dataclass
class _HeaderKeys:
    """What the header's ``# key: value`` lines said, each at most once."""

    line: LineSettings | None = None
    timing: TimingQuality | None = None
    first_index: int | None = None


class TextCaptureReader:
    """Reads the header at once; :meth:`batches` streams the data lines."""

    def __init__(self, path: str, *, follow: bool = False) -> None:
        self.path = path
        self._follow = follow
        #: Said once reading is done: e.g. a recording that was cut short.
        self.warnings: list[str] = []
        self._stream: BinaryIO = (sys.stdin.buffer if path == STDIO else
                                  cast(BinaryIO, GrowingFile(path, warnings=self.warnings)) if follow
                                  else open(path, "rb"))  # noqa: SIM115
        self._line_number = 0
        self._unterminated = False
        self._first_data: tuple[int, str] | None = None
        #: The capture's line names, and the channel of the data lines that follow.
        self._channels: tuple[str, ...] = ()
        self._channel = 0
        #: The time of the last data or ``# heard-until:`` line read: times never decrease.
        self._last_ns = -1
        #: Comment lines found among the data lines, known once :meth:`batches` is done.
        self.late_notes: list[str] = []
        #: Notes kept so far (header and late) and the bytes they hold; comment lines past the
        #: limits are counted, not kept (a stream of comments must not grow memory without end).
        self._notes_kept = self._note_bytes = self._notes_dropped = 0
        self.info = self._read_header()

    def close(self) -> None:
        if self._stream is not sys.stdin.buffer:
            self._stream.close()

    def last_time_ns(self) -> int | None:
        """The time of the last data line, read from the file's tail."""
        if self.path == STDIO:
            return None
        try:
            with open(self.path, "rb") as tail:
                tail.seek(max(os.fstat(tail.fileno()).st_size - TAIL_BYTES, 0))
                lines = tail.read().split(b"\n")
        except OSError:
            return None
        for raw in reversed(lines[1:] if len(lines) > 1 else lines):
            text = raw.decode("ascii", "replace").strip()
            if text and not text.startswith("#"):
                return parse_time_ns(text.split(maxsplit=1)[0])
        return None

    def _error(self, kind: ErrorKind, message: str, line_number: int | None = None) -> CaptureFormatError:
        number = self._line_number if line_number is None else line_number
        return CaptureFormatError(kind, message, path=self.path, location=f"line {number}")

    def _lines(self) -> Iterator[str]:
        # A line holds a time and up to max_read_bytes() bytes as hex, perhaps spaced: longer is refused
        # before it is held whole (a 100 MB line cost gigabytes).
        limit = 3 * max_read_bytes() + 64
        for raw in iter(lambda: self._stream.readline(limit + 1), b""):
            self._line_number += 1
            if len(raw) > limit:
                raise self._error(ErrorKind.BAD_DATA, read_limit_message((limit - 64) // 3))
            # Only the file's last line can lack its newline: a file cut short, or written by hand.
            self._unterminated = not raw.endswith(b"\n")
            try:
                yield raw.decode("ascii").strip()
            except UnicodeDecodeError as exc:
                raise self._error(
                    ErrorKind.BAD_DATA, f"not text: byte 0x{raw[exc.start]:02X} at column {exc.start + 1}"
                ) from None

    def _read_header(self) -> CaptureInfo:
        lines = self._lines()
        first = next(lines, None)
        if first is None:
            raise self._error(ErrorKind.BAD_HEADER, f"empty file; a capture starts with {MAGIC!r}", 1)
        if first != MAGIC:
            version = _MAGIC_ANY_VERSION.fullmatch(first)
            if version:
                raise self._error(ErrorKind.UNKNOWN_FORMAT, f"unknown format version v{version.group(1)}")
            raise self._error(ErrorKind.BAD_HEADER, f"missing header: the first line must be {MAGIC!r}")
        keys = _HeaderKeys()
        channels: tuple[str, ...] = ()
        notes: list[str] = []
        self._lines_iter = lines
        for text in lines:
            if not text:
                continue
            if not text.startswith("#"):
                self._first_data = (self._line_number, text)
                break
            key = _HEADER_KEY.match(text)
            if _UART_ERRORS.match(text):
                raise self._error(ErrorKind.BAD_DATA, "'# uart-errors:' must follow the data line it marks")
            if (named := _CHANNELS.match(text)) is not None:
                channels = self._header_channels(channels, named.group(1))
            elif (channel := _CHANNEL.match(text)) is not None:
                self._channel = self._channel_code(channels, channel.group(1))
            elif key is None:
                self._keep_note(notes, text[1:].strip())
            else:
                self._header_key(keys, key.group(1).lower(), key.group(2))
        self._channels = channels
        return CaptureInfo(line=keys.line, timing=keys.timing or TimingQuality.HOST, notes=tuple(notes),
                           channels=channels, first_index=keys.first_index or 0)

    def _header_key(self, keys: _HeaderKeys, name: str, value: str) -> None:
        if name == "line":
            keys.line = self._header_line(keys.line, value)
        elif name == "first-frame":
            keys.first_index = self._header_first_frame(keys.first_index, value)
        else:
            keys.timing = self._header_timing(keys.timing, value)

    def _header_first_frame(self, previous: int | None, value: str) -> int:
        if previous is not None:
            raise self._error(ErrorKind.BAD_HEADER, "second '# first-frame:' header")
        text = value.strip()
        if not (text.isascii() and text.isdigit()) or len(text) > 18:
            raise self._error(ErrorKind.BAD_HEADER, f"'# first-frame:' {shown(text)} is not a frame number (0 to "
                              "999999999999999999)")
        return int(text)

    def _header_channels(self, previous: tuple[str, ...], value: str) -> tuple[str, ...]:
        try:
            names = tuple(channel_name(token) for token in value.split())
        except ValueError as error:
            raise self._error(ErrorKind.BAD_HEADER, f"'# channels:' {error}") from None
        if previous:
            raise self._error(ErrorKind.BAD_HEADER, "second '# channels:' header")
        if not names or len(set(names)) != len(names) or NO_CHANNEL in value.split() or len(names) > 255:
            raise self._error(ErrorKind.BAD_HEADER, f"'# channels: {value.strip()}' must name up to 255 different "
                              "lines, e.g. '# channels: RX TX'")
        return names

    def _channel_code(self, channels: tuple[str, ...], name: str, line_number: int | None = None) -> int:
        """The 1-based code of a ``# channel:`` line's name (0 for ``-``)."""
        if name == NO_CHANNEL:
            return 0
        try:
            name = channel_name(name)
        except ValueError as error:
            raise self._error(ErrorKind.BAD_DATA, f"'# channel:' {error}", line_number) from None
        if name not in channels:
            said = " ".join(channels) if channels else "none (no '# channels:' header)"
            raise self._error(ErrorKind.BAD_DATA, f"channel {name!r} is not one of the header's: {said}", line_number)
        return channels.index(name) + 1

    def _header_line(self, previous: LineSettings | None, value: str) -> LineSettings:
        if previous is not None:
            raise self._error(ErrorKind.BAD_HEADER, "second '# line:' header")
        try:
            return LineSettings.parse(value)
        except ValueError as exc:
            raise self._error(ErrorKind.BAD_HEADER, str(exc)) from None

    def _header_timing(self, previous: TimingQuality | None, value: str) -> TimingQuality:
        if previous is not None:
            raise self._error(ErrorKind.BAD_HEADER, "second '# timing:' header")
        try:
            return TimingQuality(value.strip().lower())
        except ValueError:
            raise self._error(
                ErrorKind.BAD_HEADER, f"timing {value.strip()!r} is neither 'exact' nor 'host'"
            ) from None

    def batches(self) -> Iterator[ChunkBatch]:
        lines = _Lines()
        for line_number, text in self._data_lines():
            try:
                if text.startswith("#"):
                    self._comment(lines, line_number, text)
                    continue
                t_ns, data = self._parse_data_line(line_number, text)
                self._in_order(t_ns, "time", line_number)
            except CaptureFormatError as exc:
                if not (self._unterminated and line_number == self._line_number):
                    raise
                # The last line, without its newline, does not read: the file was cut short there.
                self.warnings.append(f"{self.path}: cut short at line {line_number} (its last line is incomplete: "
                                     f"{exc.message}); everything before it was read")
                break
            # A full batch goes once the next data line shows no error comment can follow it.
            if len(lines.times) >= BATCH_CHUNKS:
                yield lines.batch()
                lines = _Lines()
            lines.add(t_ns, data, self._channel)
            if self._follow and cast(GrowingFile, self._stream).caught_up():
                yield lines.batch()  # everything written so far: decoded now, not when a batch fills
                lines = _Lines()
        else:
            if self._unterminated:
                self.warnings.append(f"{self.path}: line {self._line_number}, the last, has no newline: the file may "
                                     "be cut short there (what the line says was read)")
        if lines.times:
            yield lines.batch()

    def _keep_note(self, notes: list[str], note: str) -> None:
        if self._notes_kept >= MAX_NOTES or self._note_bytes + len(note) > MAX_NOTE_BYTES:
            if not self._notes_dropped:
                self.warnings.append(f"{self.path}: more comment lines than rtusniff keeps as notes (the first "
                                     f"{MAX_NOTES:,}, {MAX_NOTE_BYTES // 2**20} MiB at most); the rest are not kept")
            self._notes_dropped += 1
            return
        self._notes_kept += 1
        self._note_bytes += len(note)
        notes.append(note)

    def _comment(self, lines: _Lines, line_number: int, text: str) -> None:
        """A note, a line's channel, the moment the line was heard until, or the UART errors of
        the data line just read."""
        errors = _UART_ERRORS.match(text)
        if errors is None:
            channel, heard = _CHANNEL.match(text), _HEARD_UNTIL.match(text)
            if channel is not None:
                self._channel = self._channel_code(self._channels, channel.group(1), line_number)
            elif heard is not None:
                lines.add(self._heard_until(heard.group(1), line_number), b"", self._channel)
            else:
                self._keep_note(self.late_notes, text[1:].strip())
            return
        if not lines.parts:
            raise self._error(ErrorKind.BAD_DATA, "'# uart-errors:' must follow the data line it marks",
                              line_number)
        size = len(lines.parts[-1])
        for item in errors.group(1).split(","):
            mark = _UART_MARK.fullmatch(item.strip())
            if mark is None:
                raise self._error(ErrorKind.BAD_DATA, f"bad UART error {item.strip()!r}: expected 'POSITION "
                                  "framing|parity|framing+parity'", line_number)
            position = int(mark.group(1))
            if position >= size:
                raise self._error(ErrorKind.BAD_DATA, f"UART error at byte {position} of a line of {size} "
                                  f"byte{'s' if size != 1 else ''}", line_number)
            lines.mark(position, UART_ERROR_KINDS[mark.group(2).lower()])

    def _heard_until(self, text: str, line_number: int) -> int:
        """The time of a ``# heard-until:`` line: a time as data lines have, in order with them."""
        t_ns = parse_time_ns(text)
        if t_ns is None or t_ns > MAX_TIME_NS:
            raise self._error(ErrorKind.BAD_DATA, f"'# heard-until:' {shown(text)} is not a time", line_number)
        self._in_order(t_ns, "'# heard-until:' time", line_number)
        return t_ns

    def _in_order(self, t_ns: int, what: str, line_number: int) -> None:
        """Times never decrease, data lines' and ``# heard-until:`` lines' alike."""
        if t_ns < self._last_ns:
            raise self._error(ErrorKind.DECREASING_TIME, f"{what} {format_time_ns(t_ns)} is before the previous "
                              f"line's {format_time_ns(self._last_ns)}", line_number)
        self._last_ns = t_ns

    def _data_lines(self) -> Iterator[tuple[int, str]]:
        if self._first_data is not None:
            yield self._first_data
        for text in self._lines_iter:
            if text:
                yield self._line_number, text

    def _parse_data_line(self, line_number: int, text: str) -> tuple[int, bytes]:
        time_text, _, hex_text = text.partition(" ")
        t_ns = parse_time_ns(time_text)
        if t_ns is None:
            raise self._error(
                ErrorKind.BAD_DATA,
                f"bad time {shown(time_text)}: expected seconds (up to 19 digits) with up to 9 decimals", line_number,
            )
        if t_ns > MAX_TIME_NS:
            limit = f"{MAX_TIME_NS // NS_PER_S} s (the year 2262)"
            raise self._error(ErrorKind.BAD_DATA, f"time {time_text} is beyond {limit}", line_number)
        try:
            data = bytes.fromhex(hex_text)
        except ValueError:
            raise self._error(ErrorKind.BAD_DATA, _describe_bad_hex(hex_text), line_number) from None
        if not data:
            raise self._error(ErrorKind.BAD_DATA, "a data line needs at least one byte after the time", line_number)
        return t_ns, data


def _describe_bad_hex(hex_text: str) -> str:
    digits = "".join(hex_text.split())
    for char in digits:
        if char not in "0123456789abcdefABCDEF":
            return f"bad hex digit {char!r}"
    if len(digits) % 2:
        return f"odd number of hex digits ({len(digits)})"
    return "hex bytes must be two digits each, separated by spaces or not at all"


class _Lines:
    """Data lines read for the next batch, and the UART errors their comments named."""

    def __init__(self) -> None:
        self.times: list[int] = []
        self.parts: list[bytes] = []
        self.channels: list[int] = []
        self._size = 0
        #: (offset in the batch's data, kind) of the bytes with an error.
        self._marks: list[tuple[int, int]] = []

    def add(self, t_ns: int, data: bytes, channel: int) -> None:
        self.times.append(t_ns)
        self.parts.append(data)
        self.channels.append(channel)
        self._size += len(data)

    def mark(self, position: int, kind: int) -> None:
        """``position`` of the last line added."""
        self._marks.append((self._size - len(self.parts[-1]) + position, kind))

    def batch(self) -> ChunkBatch:
        kinds = None
        if self._marks:
            kinds = np.zeros(self._size, np.uint8)
            for offset, kind in self._marks:
                kinds[offset] |= kind
        lengths = np.fromiter(map(len, self.parts), np.int64, len(self.parts))
        channels = np.array(self.channels, np.uint8) if any(self.channels) else None
        return ChunkBatch(b"".join(self.parts), np.cumsum(lengths), np.array(self.times, dtype=np.int64), kinds,
                          channels)


#: A note line that would read as a header or an extension line gets this in front.
FORMAT = CaptureFormat(
    name="text",
    suffixes=(".log", ".txt", ".rtu"),
    description="rtu-capture v1 text: one line per chunk, 'SECONDS.NANOS HEX...'",
    # Any version: a file of another version is recognised, and its reader says why it cannot read it.
    sniff=lambda head: head.startswith(b"# rtu-capture"),
    open_reader=lambda path, options: TextCaptureReader(path, follow=options.follow),
    open_writer=TextCaptureWriter,
    followable=True,
)
