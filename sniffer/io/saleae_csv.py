"""Saleae Logic's Async Serial analyzer exports (CSV), read as captures.

Two layouts, told apart by their header line:

* **Logic 2** data table (``File → Export Data Table``, Logic 2.x; the layout its Python
  automation API's ``export_data_table`` writes too): ``name,type,start_time,duration,data``,
  one ``data`` row per character, ``start_time`` and ``duration`` in seconds from the capture's
  start, ``data`` as ``0xC8`` (or the character itself with ASCII display), an optional
  ``error`` column (``framing``, ``parity``) — each character ends at ``start_time + duration``;
* **Logic 1.x** serial export: ``Time [s],Value,Parity Error,Framing Error``, the time of each
  character's start bit, ``Value`` as ``0x48`` (or ``'H'``, or a number) — each character ends a
  character time (``--line``) after it starts.

A logic analyzer's times: ``exact`` timing. The exports carry no date: times are seconds from
the capture's start, on 1970-01-01 (the notes say so). They carry no line settings either:
``--line`` gives them. Characters with an error are kept with it (a parity error where the text
names parity, a framing error where it names framing or anything else the analyzer reports: the
character cannot be trusted) and counted in a warning. A row that cannot be read is one error
naming the file and its line.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterator
from dataclasses import replace
from typing import TextIO

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality, UartError
from decoders.uart import character_chunks, decode_transitions, merge_characters
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io.base import ChannelChoiceError, ReaderOptions, chosen_channels
from sniffer.io.polarity import chosen_polarity

LOGIC2 = ("name", "type", "start_time", "duration", "data")
LOGIC1 = ("Time [s]", "Value", "Parity Error", "Framing Error")
BATCH_CHUNKS = 4096
NS_PER_S = 1_000_000_000
#: A byte as Logic writes it in each radix: 0x48, 0b01001000, 72.
_NUMBER = re.compile(r"0[xX]([0-9A-Fa-f]{1,2})|0[bB]([01]{1,8})|([0-9]{1,3})")
_ESCAPES = {"\\0": 0, "\\t": 9, "\\n": 10, "\\r": 13, "\\\\": 92, "' '": 32}


class SaleaeCsvReader:
    """Reads a Logic 2 data table or a Logic 1.x serial export (see the module docstring)."""

    def __init__(self, path: str, options: ReaderOptions) -> None:
        self.path = path
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        try:
            self._file: TextIO = open(path, encoding="utf-8-sig", newline="")  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise CaptureFormatError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from None
        self._reader = csv.reader(self._file)
        self._rows = self._read_rows()
        try:
            header = [cell.strip() for cell in next(self._rows, [])]
            if tuple(header[: len(LOGIC2)]) == LOGIC2:
                self._logic2, self._error_column = True, header.index("error") if "error" in header else None
            elif tuple(header[: len(LOGIC1)]) == LOGIC1:
                self._logic2, self._error_column = False, None
            else:
                raise self._error(f"header {','.join(header)!r} is neither a Logic 2 data table "
                                  f"({','.join(LOGIC2)}) nor a Logic 1.x serial export ({','.join(LOGIC1)})",
                                  ErrorKind.BAD_HEADER, 1)
            if options.line is None:
                raise self._error("a Saleae export does not say the line's settings: give --line, e.g. "
                                  "--line 19200 8E1", ErrorKind.NO_LINE_SETTINGS, 1)
        except BaseException:
            self._file.close()
            raise
        self._char_ns = round(options.line.bits_per_char * NS_PER_S / options.line.baud)
        version = "Logic 2 data table" if self._logic2 else "Logic 1.x serial export"
        self.info = CaptureInfo(options.line, TimingQuality.EXACT, (
            f"Saleae {version} {path}: times are seconds from the capture's start (the export has no date)",))

    def _error(self, message: str, kind: ErrorKind = ErrorKind.BAD_DATA, line: int | None = None
               ) -> CaptureFormatError:
        return CaptureFormatError(kind, message, path=self.path, location=f"line {line or self._reader.line_num}")

    def _read_rows(self) -> Iterator[list[str]]:
        """The CSV's rows; what is not UTF-8 text or not CSV is an error naming the line."""
        while True:
            try:
                row = next(self._reader, None)
            except UnicodeDecodeError as exc:
                raise self._error(f"not text: byte 0x{exc.object[exc.start]:02X}",
                                  line=self._reader.line_num + 1) from None
            except csv.Error as exc:
                raise self._error(f"not CSV: {exc}") from None
            if row is None:
                return
            yield row

    def _characters(self) -> Iterator[tuple[int, int, str]]:
        """(end time, value, error or "") of each character, in file order."""
        for row in self._rows:
            if not row or not any(cell.strip() for cell in row):
                continue
            if self._logic2:
                if len(row) < len(LOGIC2):
                    raise self._error(f"{len(row)} columns where the header has {len(LOGIC2)} or more")
                if row[1].strip() != "data":
                    continue  # the analyzer's other rows (errors of its own, markers) carry no character
                start, duration = self._seconds(row[2]), self._seconds(row[3])
                error = row[self._error_column].strip() if self._error_column is not None and \
                    self._error_column < len(row) else ""
                yield start + duration, self._value(row[4]), error
            else:
                if len(row) < 2:
                    raise self._error("a row needs a time and a value")
                errors = [name for name, cell in zip(("parity", "framing"), row[2:4], strict=False)
                          if cell.strip() not in ("", "0")]
                yield self._seconds(row[0]) + self._char_ns, self._value(row[1]), " ".join(errors)

    def _seconds(self, text: str) -> int:
        try:
            seconds = float(text)
        except ValueError:
            raise self._error(f"{text.strip()!r} is not a time in seconds") from None
        if not 0 <= seconds < 2**33:
            raise self._error(f"time {seconds} s is outside the capture")
        return round(seconds * NS_PER_S)

    def _value(self, text: str) -> int:
        cell = text.strip()
        value: int | None = None
        if cell in _ESCAPES:
            value = _ESCAPES[cell]
        elif len(cell) == 3 and cell[0] == cell[2] == "'":
            value = ord(cell[1])
        elif len(cell) == 1:
            value = ord(cell)
        elif (number := _NUMBER.fullmatch(cell)) is not None:
            # Logic's radixes, ASCII digits only (int() would take "0x1_2", "0o17" or "٧٢" too)
            digits, base = next((text, base) for text, base in zip(number.groups(), (16, 2, 10), strict=True) if text)
            value = int(digits, base)
        if value is None or not 0 <= value <= 0xFF:
            raise self._error(f"{cell!r} is not a byte (0x48, 72, 0b01001000, 'H')")
        return value

    def batches(self) -> Iterator[ChunkBatch]:
        times: list[int] = []
        values, kinds = bytearray(), bytearray()
        previous, errors = -1, 0
        for end, value, error in self._characters():
            if end < previous:
                raise self._error("goes back in time from the character before", ErrorKind.DECREASING_TIME)
            previous = end
            errors += bool(error)
            times.append(end)
            values.append(value)
            kinds.append(error_kind(error))
            if len(values) >= BATCH_CHUNKS:
                yield _batch(times, values, kinds)
                times, values, kinds = [], bytearray(), bytearray()
        if values:
            yield _batch(times, values, kinds)
        if errors:
            self.warnings.append(f"{self.path}: {errors} characters with a framing or parity error; kept as read")

    def last_time_ns(self) -> int | None:
        return None

    def close(self) -> None:
        self._file.close()


def _finite_seconds(text: str) -> float:
    """A digital export's time; ``ValueError`` for one that is no number, NaN or infinite."""
    seconds = float(text)
    if not math.isfinite(seconds) or abs(seconds) >= 2**33:
        raise ValueError(f"time {text.strip()!r} is not a time in seconds")
    return seconds


def error_kind(text: str) -> int:
    """The :class:`UartError` kind of an analyzer's error text (see the module docstring)."""
    if not text:
        return UartError.NONE
    lowered = text.lower()
    kind = (UartError.PARITY if "parity" in lowered else 0) | (UartError.FRAMING if "fram" in lowered else 0)
    return int(kind or UartError.FRAMING)


def _batch(times: list[int], values: bytearray, kinds: bytearray) -> ChunkBatch:
    marks = np.frombuffer(bytes(kinds), np.uint8)
    return ChunkBatch(bytes(values), np.arange(1, len(values) + 1, dtype=np.int64), np.array(times, np.int64),
                      marks if marks.any() else None)


#: Rows of a digital export (a row where a channel changes) decoded both ways to tell a line's polarity.
POLARITY_ROWS = 200_000


class SaleaeDigitalReader:
    """Saleae Logic's raw digital export (CSV: ``Time [s],<channel>,<channel>…``, a row where a
    channel changes, ``0``/``1``), decoded as UART by :func:`decoders.uart.decode_transitions`:
    the bus's channel is ``--channel`` (a name, or a number from 1) or the only one that changes,
    ``--channel`` twice for RX and TX (merged in time order, each character keeping its channel);
    a line is read inverted where its transitions say so (:mod:`sniffer.io.polarity`); ``--line``
    gives the UART settings."""

    def __init__(self, path: str, options: ReaderOptions) -> None:
        self.path = path
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        with open(path, encoding="utf-8-sig", newline="") as file:
            rows = csv.reader(file)
            try:
                names = [cell.strip() for cell in next(rows, [])][1:]
                times, states = [], []
                for row in rows:
                    if row:
                        times.append(_finite_seconds(row[0]))
                        states.append([cell.strip() == "1" for cell in row[1 : 1 + len(names)]])
                        if len(states[-1]) != len(names):
                            raise ValueError(f"{len(row)} columns where the header has {len(names) + 1}")
            except (UnicodeDecodeError, csv.Error, ValueError) as exc:
                raise CaptureFormatError(ErrorKind.BAD_DATA, f"not a digital export row: {exc}", path=path,
                                         location=f"line {rows.line_num}") from None
        if options.line is None:
            raise CaptureFormatError(ErrorKind.NO_LINE_SETTINGS, "a Saleae export does not say the line's "
                                     "settings: give --line, e.g. --line 19200 8E1", path=path, location="line 1")
        self._times = np.array(times, np.float64)
        if len(self._times) and np.any(np.diff(self._times) < 0):
            raise CaptureFormatError(ErrorKind.DECREASING_TIME, "rows go back in time", path=path,
                                     location=f"line {int(np.argmax(np.diff(self._times) < 0)) + 3}")
        matrix = np.array(states, np.bool_).reshape(len(times), len(names))
        columns = self._columns(names, matrix, options.channels)
        self._levels = [matrix[:, column] for column in columns]
        self._line = options.line
        self._inverted = [self._polarity(levels, names[column], options.invert)
                          for levels, column in zip(self._levels, columns, strict=True)]
        said = ", ".join(f"{names[column]}{' (inverted)' if inverted else ''}"
                         for column, inverted in zip(columns, self._inverted, strict=True))
        notes = (f"Saleae digital export {path}: channel {said}, decoded as UART {options.line.format()} by "
                 "rtusniff; times are seconds from the capture's start",)
        self.info = CaptureInfo(options.line, TimingQuality.EXACT, notes,
                                tuple(names[c] for c in columns) if len(columns) > 1 else ())

    def _polarity(self, levels: npt.NDArray[np.bool_], name: str, forced: bool | None) -> bool:
        """Whether a channel reads inverted, by what its first rows decode to
        (:func:`~sniffer.io.polarity.chosen_polarity`), said in a warning where it is inverted."""
        first = slice(0, POLARITY_ROWS)
        inverted, said = chosen_polarity(
            lambda upside_down: decode_transitions(self._times[first], levels[first], self._line, inverted=upside_down),
            starts_low=bool(len(levels)) and not bool(levels[0]), forced=forced, name=f"channel {name}")
        if said is not None:
            self.warnings.append(f"{self.path}: {said}")
        return inverted

    def _columns(self, names: list[str], matrix: np.ndarray, channels: tuple[str, ...]) -> list[int]:
        """The columns of ``--channel`` (at most two: RX and TX), else of the only one that changes."""
        if len(channels) > 2:
            raise CaptureFormatError(ErrorKind.USAGE, f"{len(channels)} --channel options: a bus has one line, or "
                                     "two (RX and TX)", path=self.path, location="line 1")
        if channels:
            try:
                numbers, said = chosen_channels(channels, {i + 1: name for i, name in enumerate(names)})
            except ChannelChoiceError as exc:
                raise CaptureFormatError(ErrorKind.USAGE, str(exc), path=self.path, location="line 1") from None
            self.warnings += [f"{self.path}: {warning}" for warning in said]
            return [number - 1 for number in numbers]
        return [self._changing(names, matrix)]

    def _changing(self, names: list[str], matrix: np.ndarray) -> int:
        changing = [i for i in range(len(names)) if len(matrix) and np.any(matrix[:, i] != matrix[0, i])]
        if len(changing) != 1:
            listed = ", ".join(names[i] for i in (changing or range(len(names))))
            raise CaptureFormatError(ErrorKind.USAGE, f"{'several' if changing else 'no'} channels change ({listed}); "
                                     "choose the line's with --channel NAME", path=self.path, location="line 1")
        return changing[0]

    def batches(self) -> Iterator[ChunkBatch]:
        parts = [decode_transitions(self._times, levels, self._line, inverted=inverted)
                 for levels, inverted in zip(self._levels, self._inverted, strict=True)]
        if len(parts) > 1:
            parts = [replace(part, channels=np.full(len(part), channel, np.uint8))
                     for channel, part in enumerate(parts, start=1)]
        characters = merge_characters(parts)
        errors = int((characters.framing_errors | characters.parity_errors).sum())
        if len(characters):
            yield character_chunks(characters, t0_ns=0, unit_s=1.0)
        if errors:
            self.warnings.append(f"{self.path}: {errors} characters with a framing or parity error; kept as sampled")

    def last_time_ns(self) -> int | None:
        return None

    def close(self) -> None:
        """Read whole when opened: nothing is held."""


def open_saleae(path: str, options: ReaderOptions) -> SaleaeCsvReader | SaleaeDigitalReader:
    """The reader for the layout the header names: a serial export or a raw digital one."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as file:
            header = file.readline()
    except OSError as exc:
        raise CaptureFormatError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc.strerror}", path=path) from None
    cells = [cell.strip() for cell in header.split(",")]
    if len(cells) >= 2 and cells[0].startswith("Time") and cells[1] != "Value":
        return SaleaeDigitalReader(path, options)
    return SaleaeCsvReader(path, options)
