"""Serial line settings and the Modbus RTU timing they imply.

All times are nanoseconds. A character time is not a whole number of nanoseconds
(11 bits at 19200 Bd = 572 916.67 ns), so the timing properties are floats; the
framer compares integer timestamps against them with a half-nanosecond tolerance.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import Enum

#: Above this baud rate the Modbus serial-line specification (V1.02, 2.5.1.1)
#: fixes t1.5 and t3.5 instead of scaling them with the character time.
FIXED_TIMING_ABOVE_BAUD = 19200
FIXED_T1_5_NS = 750_000.0
FIXED_T3_5_NS = 1_750_000.0

MIN_BAUD = 50
MAX_BAUD = 4_000_000

_LINE_RE = re.compile(r"^\s*(\d+)\s+([5-9])([NEOMS])([12])\s*$", re.IGNORECASE | re.ASCII)


class Parity(Enum):
    """Parity of a serial character, by its one-letter code."""

    NONE = "N"
    EVEN = "E"
    ODD = "O"
    MARK = "M"
    SPACE = "S"


@dataclass(frozen=True, slots=True)
class LineSettings:
    """Baud rate and character format of one RS485 line.

    ``char_timing`` selects pure character multiples for t1.5/t3.5 at every baud
    rate; by default the specification's fixed 750 µs / 1750 µs apply above 19200 Bd.
    """

    baud: int
    data_bits: int = 8
    parity: Parity = Parity.EVEN
    stop_bits: int = 1
    char_timing: bool = False

    def __post_init__(self) -> None:
        if not MIN_BAUD <= self.baud <= MAX_BAUD:
            raise ValueError(f"baud rate {self.baud} is outside {MIN_BAUD}..{MAX_BAUD}")
        if self.data_bits == 9:
            raise ValueError("9 data bits: a 9-bit character does not fit the bytes rtusniff captures "
                             "(Modbus RTU uses 8 data bits)")
        if not 5 <= self.data_bits <= 8:
            raise ValueError(f"data bits {self.data_bits} is outside 5..8")
        if self.stop_bits not in (1, 2):
            raise ValueError(f"stop bits {self.stop_bits} must be 1 or 2")

    @classmethod
    def parse(cls, text: str, *, char_timing: bool = False) -> LineSettings:
        """Parse ``"19200 8E1"`` (baud, then data bits, parity letter, stop bits)."""
        match = _LINE_RE.match(text)
        if match is None:
            raise ValueError(
                f"line settings {text!r} are not 'BAUD FORMAT' such as '19200 8E1' "
                "(data bits 5-8, parity N/E/O/M/S, stop bits 1 or 2)"
            )
        baud, data_bits, parity, stop_bits = match.groups()
        return cls(
            baud=int(baud),
            data_bits=int(data_bits),
            parity=Parity(parity.upper()),
            stop_bits=int(stop_bits),
            char_timing=char_timing,
        )

    def format(self) -> str:
        """The ``BAUD FORMAT`` text that :meth:`parse` reads."""
        return f"{self.baud} {self.data_bits}{self.parity.value}{self.stop_bits}"

    @property
    def bits_per_char(self) -> int:
        """Start bit + data bits + parity bit (if any) + stop bits."""
        return 1 + self.data_bits + (0 if self.parity is Parity.NONE else 1) + self.stop_bits

    @property
    def char_time_ns(self) -> float:
        """Time one character occupies on the wire."""
        return self.bits_per_char * 1e9 / self.baud

    @property
    def uses_fixed_timing(self) -> bool:
        """True where t1.5/t3.5 are the specification's fixed values."""
        return not self.char_timing and self.baud > FIXED_TIMING_ABOVE_BAUD

    @property
    def t1_5_ns(self) -> float:
        """Longest silence allowed between two characters of one frame."""
        return FIXED_T1_5_NS if self.uses_fixed_timing else 1.5 * self.char_time_ns

    @property
    def t3_5_ns(self) -> float:
        """Shortest silence that separates two frames."""
        return FIXED_T3_5_NS if self.uses_fixed_timing else 3.5 * self.char_time_ns
