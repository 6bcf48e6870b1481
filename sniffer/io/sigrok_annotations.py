"""sigrok-cli's UART annotations, read as a capture: for people who already decode with sigrok.

The text ``sigrok-cli -i REC.sr -P uart:baudrate=…:rx=…:tx=… -A uart --protocol-decoder-samplenum``
prints (with ``--protocol-decoder-ann-class``, the class after the decoder's name)::

    14-84 uart: tx-data: "48"
    83-92 uart: tx-stop: "Stop bit" "Stop" "T"

Each ``rx-data`` / ``tx-data`` line is a character, its value as sigrok's ``format`` writes it:
``hex`` (the default: ``48``) or ``ascii`` (``H``, ``[0D]`` for what is not printable); RX and TX
lines merge in time order, each character keeping its direction as its channel (``rx``, ``tx``).
The text has sample numbers, not times: the sample rate is read from the data annotations,
which span the data bits (``--line`` says how many, and the baud rate), and each character
ends its parity and stop bits after its data. Times are seconds from the recording's start
(no date). A ``*-parity-err`` line marks the character of its direction just
read with a parity error; a ``*-warning`` line saying "Frame error" (sigrok's stop-bit check),
a ``*-frame-err`` or a ``*-break`` line marks it with a framing error; all are counted in a
warning. An error line with no character of its direction before it is counted only.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import TextIO

import numpy as np

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality, UartError
from decoders.line import Parity
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io.base import ReaderOptions

#: START-END decoder: class: "text" ... (greedy: sigrok's ascii format writes a quote unescaped: """);
#: sample numbers of ASCII digits that fit 64 bits.
LINE = re.compile(r"([0-9]{1,18})-([0-9]{1,18}) ([\w.-]+): ([\w-]+): \"(.*)\"\s*$")
_HEX_BYTE = re.compile("[0-9A-Fa-f]{1,2}")
#: What to run for the annotations read here (said where a file holds another decoder's only).
UART_COMMAND = ("sigrok-cli -i REC.sr -P uart:baudrate=BAUD:rx=RX -A uart --protocol-decoder-samplenum "
                "--protocol-decoder-ann-class")
NS_PER_S = 1_000_000_000
#: Data annotations looked at to tell the sample rate.
RATE_SAMPLE = 256


class SigrokAnnotationsReader:
    """Reads sigrok-cli's UART annotation text (see the module docstring)."""

    def __init__(self, path: str, options: ReaderOptions) -> None:
        self.path = path
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        try:
            with open(path, encoding="utf-8") as text:
                starts, ends, values, kinds, directions = self._read(text)
        except UnicodeDecodeError as exc:
            raise CaptureFormatError(ErrorKind.BAD_DATA, f"not text: byte 0x{exc.object[exc.start]:02X}",
                                     path=path, location=f"byte {exc.start}") from None
        if not values and self._others:
            decoder, number = next(iter(self._others.items()))
            raise CaptureFormatError(ErrorKind.BAD_DATA, f"the annotations of sigrok's {decoder!r} decoder, not of its "
                                     f"UART decoder, which rtusniff decodes from: export them with {UART_COMMAND}",
                                     path=path, location=f"line {number}")
        if not values:
            raise CaptureFormatError(ErrorKind.NO_DATA, "no rx-data or tx-data annotations (run sigrok-cli with "
                                     "-A uart and --protocol-decoder-samplenum)", path=path, location="line 1")
        if self._others:
            listed = ", ".join(repr(decoder) for decoder in self._others)
            self.warnings.append(f"{path}: the annotations of sigrok's {listed} decoder left out: the UART "
                                 "decoder's characters are what rtusniff decodes")
        if options.line is None:
            raise CaptureFormatError(ErrorKind.NO_LINE_SETTINGS, "sigrok-cli's annotations do not say the UART "
                                     "settings: give --line, e.g. --line 9600 8N1", path=path, location="line 1")
        self._line = options.line
        spans = np.array(ends[:RATE_SAMPLE], np.float64) - np.array(starts[:RATE_SAMPLE], np.float64)
        bit_samples = float(np.median(spans)) / self._line.data_bits
        self._rate = bit_samples * self._line.baud
        tail = (0 if self._line.parity is Parity.NONE else 1) + self._line.stop_bits
        order = np.argsort(np.array(ends, np.float64), kind="stable")
        self._ends = np.round((np.array(ends, np.float64)[order] + tail * bit_samples) / self._rate
                              * NS_PER_S).astype(np.int64)
        self._values = np.array(values, np.uint8)[order]
        marks = np.array(kinds, np.uint8)[order]
        self._kinds = marks if marks.any() else None
        # RX and TX both there: each character says which (its channel).
        names = tuple(sorted(set(directions)))
        self._channels = np.array([names.index(d) + 1 for d in directions], np.uint8)[order] if len(names) > 1 \
            else None
        self.info = CaptureInfo(options.line, TimingQuality.EXACT, (
            f"sigrok-cli UART annotations {path}: sample rate {self._rate:,.0f} Hz read from the data bits' spans; "
            "times are seconds from the recording's start",), names if len(names) > 1 else ())

    def _read(self, text: TextIO) -> tuple[list[int], list[int], list[int], list[int], list[str]]:
        starts: list[int] = []
        directions: list[str] = []
        ends: list[int] = []
        values: list[int] = []
        kinds: list[int] = []
        #: The last character read per direction (``rx``, ``tx``): what an error line marks.
        last: dict[str, int] = {}
        self._errors = 0
        #: Decoders other than the UART's, with the first line of each (a stacked decoder's output).
        self._others: dict[str, int] = {}
        for number, raw in enumerate(text, start=1):
            line = raw.strip()
            if not line:
                continue
            match = LINE.match(line)
            if match is None:
                raise CaptureFormatError(ErrorKind.BAD_DATA, "not a sigrok-cli annotation line with sample numbers "
                                         "and class (START-END uart: CLASS: \"TEXT\")", path=self.path,
                                         location=f"line {number}")
            if not match[3].startswith("uart"):
                self._others.setdefault(match[3], number)
                continue
            kind = match[4]
            direction = kind.split("-", 1)[0]
            if kind.endswith("-data"):
                if direction not in ("rx", "tx"):  # sigrok's UART decoder has these two
                    raise CaptureFormatError(ErrorKind.BAD_DATA, f"class {kind!r} is neither rx-data nor tx-data",
                                             path=self.path, location=f"line {number}")
                last[direction] = len(values)
                starts.append(int(match[1]))
                ends.append(int(match[2]))
                values.append(self._value(match[5], number))
                kinds.append(0)
                directions.append(direction)
            elif (error := _error_kind(kind, match[5])) is not None:
                self._errors += 1
                if direction in last:
                    kinds[last[direction]] |= error
        return starts, ends, values, kinds, directions

    def _value(self, text: str, number: int) -> int:
        if len(text) == 4 and text[0] == "[" and text[3] == "]":
            text = text[1:3]
        elif len(text) == 1:
            return ord(text)
        elif len(text) == 2 and text[0] == "\\":
            return ord(text[1])
        # Two ASCII hex digits, as sigrok writes them (int() would take "0x1f", "1_2" or "٧٢" too).
        value = int(text, 16) if _HEX_BYTE.fullmatch(text) else -1
        if not 0 <= value <= 0xFF:
            raise CaptureFormatError(ErrorKind.BAD_DATA, f"{text!r} is not a byte as sigrok's hex or ascii format "
                                     "writes it", path=self.path, location=f"line {number}")
        return value

    def batches(self) -> Iterator[ChunkBatch]:
        if len(self._values):
            yield ChunkBatch(self._values.tobytes(), np.arange(1, len(self._values) + 1, dtype=np.int64), self._ends,
                             self._kinds, self._channels)
        if self._errors:
            self.warnings.append(f"{self.path}: {self._errors} parity or framing error annotations; the characters "
                                 "are kept as decoded, marked with their errors")

    def last_time_ns(self) -> int | None:
        return int(self._ends[-1]) if len(self._ends) else None

    def close(self) -> None:
        """Read whole when opened: nothing is held."""


def _error_kind(kind: str, text: str) -> int | None:
    """The :class:`UartError` an annotation line reports; ``None`` for the other classes."""
    if kind.endswith("-parity-err"):
        return int(UartError.PARITY)
    if kind.endswith(("-frame-err", "-frame-error", "-break")) or (
            kind.endswith(("-warning", "-warnings")) and "frame" in text.lower()):
        return int(UartError.FRAMING)
    return None
