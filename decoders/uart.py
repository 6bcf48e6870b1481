"""UART characters from a logic analyzer's samples of one line, decoded with numpy.

As sigrok's UART decoder does it: the line idles high (``inverted``: low); a character starts at a
falling edge; each bit is read at the middle of its slot (``start + (k + ½) × bit width``, slot 0
the start bit); a start bit that is high again at its middle was a glitch, and the search goes on
from there; a stop bit that is low at its middle is a framing error, a parity bit that does not
match a parity error — the character is kept either way, with its error. The next character is
looked for from the middle of the (first) stop bit. Each character ends at the end of its last
stop bit: ``start + (1 + data + parity + stop) × bit width``.

The search is vectorised: every falling edge is a candidate start; where each candidate's next
search begins is computed for all at once, and only the chain of starts actually taken is
walked, one step per character. Samples come in pieces (:class:`UartDecoder` keeps what a
character cut by the end of a piece needs).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from decoders.capture import ChunkBatch, UartError
from decoders.line import Parity

Samples = npt.NDArray[np.bool_]


class CharacterShape(Protocol):
    """What the decoder reads of a line's settings: :class:`LineSettings` (5-8 data bits, what a
    capture's bytes hold) or a :class:`CharacterFormat` (5-9)."""

    @property
    def baud(self) -> int: ...
    @property
    def data_bits(self) -> int: ...
    @property
    def parity(self) -> Parity: ...
    @property
    def stop_bits(self) -> float: ...


@dataclass(frozen=True)
class CharacterFormat:
    """A UART character format of 5 to 9 data bits and 1, 1.5 or 2 stop bits: what sigrok's
    decoder reads. A capture's :class:`LineSettings` holds 5-8 data bits (a byte) and 1 or 2 stop
    bits (Modbus RTU's); this is for the decoder alone."""

    baud: int
    data_bits: int
    parity: Parity = Parity.NONE
    stop_bits: float = 1

    def __post_init__(self) -> None:
        if not 5 <= self.data_bits <= 9:
            raise ValueError(f"data bits {self.data_bits} is outside 5..9")
        if self.stop_bits not in (1, 1.5, 2):
            raise ValueError(f"stop bits {self.stop_bits} must be 1, 1.5 or 2")


@dataclass(frozen=True)
class UartCharacters:
    """Characters in columns: value, first and end sample (absolute, as floats), errors."""

    values: npt.NDArray[np.uint16]
    start_samples: npt.NDArray[np.float64]
    end_samples: npt.NDArray[np.float64]
    framing_errors: npt.NDArray[np.bool_]
    parity_errors: npt.NDArray[np.bool_]
    #: The line (1-based: RX, TX...) of each character, when several are decoded; else ``None``.
    channels: npt.NDArray[np.uint8] | None = None

    def __len__(self) -> int:
        return len(self.values)

    def slice(self, start: int, stop: int) -> UartCharacters:
        return UartCharacters(self.values[start:stop], self.start_samples[start:stop], self.end_samples[start:stop],
                              self.framing_errors[start:stop], self.parity_errors[start:stop],
                              None if self.channels is None else self.channels[start:stop])


def character_chunks(characters: UartCharacters, *, t0_ns: int, unit_s: float) -> ChunkBatch:
    """A chunk per character (its byte: at most 8 data bits) at the end of its stop bit:
    ``t0_ns`` plus its end in units of ``unit_s`` seconds (a sample's time, or 1.0), with its
    framing and parity errors."""
    ends = t0_ns + np.round(characters.end_samples * (unit_s * 1e9)).astype(np.int64)
    data = (characters.values & 0xFF).astype(np.uint8).tobytes()
    kinds = (characters.framing_errors * np.uint8(UartError.FRAMING)
             | characters.parity_errors * np.uint8(UartError.PARITY)).astype(np.uint8)
    return ChunkBatch(data, np.arange(1, len(data) + 1, dtype=np.int64), ends, kinds if kinds.any() else None,
                      characters.channels)


def merge_characters(parts: list[UartCharacters]) -> UartCharacters:
    """The characters of several lines (RX and TX) as one stream in order of their ends."""
    parts = [part for part in parts if len(part)]
    if not parts:
        return _empty()
    joined = UartCharacters(*(np.concatenate([getattr(part, name) for part in parts])
                              for name in ("values", "start_samples", "end_samples", "framing_errors",
                                           "parity_errors")))
    on_channels = [part.channels for part in parts if part.channels is not None]
    order = np.argsort(joined.end_samples, kind="stable")
    return UartCharacters(joined.values[order], joined.start_samples[order], joined.end_samples[order],
                          joined.framing_errors[order], joined.parity_errors[order],
                          np.concatenate(on_channels)[order] if len(on_channels) == len(parts) else None)


def _empty() -> UartCharacters:
    return UartCharacters(np.zeros(0, np.uint16), np.zeros(0), np.zeros(0), np.zeros(0, np.bool_),
                          np.zeros(0, np.bool_))


@dataclass
class UartDecoder:
    """Decodes a line's samples piece by piece (``feed``), in order; ``samplerate`` in Hz."""

    line: CharacterShape
    samplerate: float
    inverted: bool = False
    #: Samples kept from the last piece (a character may start there) and the absolute number
    #: of the first of them.
    _kept: Samples = field(default_factory=lambda: np.zeros(0, np.bool_))
    _kept_from: int = 0
    #: The absolute sample from which the next start bit is looked for.
    _search_from: int = 0

    @property
    def bit_width(self) -> float:
        return self.samplerate / self.line.baud

    @property
    def _slots(self) -> float:
        return 1 + self.line.data_bits + (0 if self.line.parity is Parity.NONE else 1) + self.line.stop_bits

    def feed(self, samples: Samples) -> UartCharacters:
        """The characters whose stop bit's middle lies in what was fed so far."""
        level = np.concatenate([self._kept, samples != self.inverted])
        base = self._kept_from
        width = self.bit_width
        # A falling edge: high before, low at the sample (a line that starts low starts nothing).
        edges = np.flatnonzero(level[1:] < level[:-1]) + 1
        edges = edges[edges + base >= self._search_from]
        stop_middle = (self._slots - self.line.stop_bits + 0.5) * width
        reach = np.floor(edges + stop_middle).astype(np.int64)
        complete = reach < len(level)
        edges, reach = edges[complete], reach[complete]
        start_ok = ~level[np.floor(edges + width / 2).astype(np.int64)]
        resume = np.where(start_ok, reach, np.floor(edges + width / 2).astype(np.int64))
        following = np.searchsorted(edges, resume, "left")
        taken = _chain(following, start_ok, len(edges))
        starts = edges[taken]
        characters = self._read(level, starts, base)
        # Keep from where the search goes on: after the last character, or the last edge looked at.
        if len(taken):
            search = int(reach[taken[-1]])
        elif len(edges):
            search = int(resume[-1])
        else:
            search = max(self._search_from - base, 0)
        search = max(search, 0)
        # Only the samples a start not yet complete needs go on to the next piece (one more before
        # it, for its edge): a long idle line is not carried along.
        keep_from = min(max(search, len(level) - int(np.ceil(stop_middle)) - 2, 0), len(level))
        self._search_from = base + search
        self._kept, self._kept_from = level[keep_from:], base + keep_from
        return characters

    def _read(self, level: Samples, starts: npt.NDArray[np.int64], base: int) -> UartCharacters:
        width = self.bit_width

        def at(slot: float) -> Samples:
            """The line at the middle of ``slot`` of every character (0: the start bit)."""
            return np.asarray(level[np.floor(starts + (slot + 0.5) * width).astype(np.int64)], np.bool_)

        absolute = (starts + base).astype(np.float64)
        return read_characters(self.line, at, absolute, absolute + self._slots * width)


def read_characters(line: CharacterShape, at: Callable[[float], Samples], starts: npt.NDArray[np.float64],
                    ends: npt.NDArray[np.float64]) -> UartCharacters:
    """The characters whose start bits begin at ``starts``: their data bits (least significant
    first), parity and stop bits read by ``at(slot)``, the line at the middle of a bit slot of
    every character. One reading for samples and for transitions."""
    if not len(starts):
        return _empty()
    bits = np.stack([at(slot) for slot in range(1, 1 + line.data_bits)], axis=1)
    weights = (1 << np.arange(line.data_bits)).astype(np.uint16)
    values = (bits * weights).sum(axis=1).astype(np.uint16)
    slot = 1 + line.data_bits
    parity_errors = np.zeros(len(starts), np.bool_)
    if line.parity is not Parity.NONE:
        ones = bits.sum(axis=1) % 2 == 1
        expected = {Parity.EVEN: ones, Parity.ODD: ~ones, Parity.MARK: np.ones_like(ones),
                    Parity.SPACE: np.zeros_like(ones)}[line.parity]
        parity_errors = at(slot) != expected
        slot += 1
    return UartCharacters(values, starts, ends, ~at(slot), parity_errors)


def _chain(following: npt.NDArray[np.int64], start_ok: npt.NDArray[np.bool_], count: int) -> npt.NDArray[np.int64]:
    """The candidate starts taken, following ``following`` from the first: only real starts
    (``start_ok``) are characters; a glitch moves the search on without one."""
    taken: list[int] = []
    nexts, oks = following.tolist(), start_ok.tolist()
    at = 0
    while at < count:
        if oks[at]:
            taken.append(at)
        at = nexts[at] if nexts[at] > at else at + 1
    return np.array(taken, np.int64)


#: The rates serial ports and Modbus devices use, the commonest first (where two read alike, the
#: earlier is taken), then rates only some UARTs or other buses use (DMX, MIDI-like, 1 Mbd).
STANDARD_BAUDS = (9600, 19200, 38400, 57600, 115200, 4800, 2400, 1200, 230400, 460800, 921600, 14400, 28800,
                  76800, 600, 300, 250000, 500000, 1000000)
#: A standard rate is a candidate where the line's pulses measure within this share of it: a bit
#: a few samples long is measured to a sample, so 460 800 Bd at 5 MHz (10.85 samples a bit) is as
#: near 500 000 Bd as to itself, and which one the characters read with fewer errors says.
BAUD_TOLERANCE = 0.12


def pulse_baud(level: Samples, samplerate: float) -> float | None:
    """The baud rate the line's one-bit pulses measure, or ``None`` with too few edges to tell. A
    bit is the shortest time the line holds a level; its pulses, sampled, last a whole number of
    samples either side of it, so those near the shortest are averaged rather than the shortest
    taken."""
    edges = np.flatnonzero(level[1:] != level[:-1])
    if len(edges) < 20:
        return None
    runs = np.diff(edges)
    shortest = float(np.percentile(runs, 2))
    one_bit = runs[(runs >= shortest) & (runs < 1.5 * shortest)]
    if not len(one_bit):  # a few edges, the shortest pulses glitches far from any bit: no measure
        return None
    return samplerate / max(float(one_bit.mean()), 1.0)


def baud_candidates(measured: float) -> list[int]:
    """The standard rates within :data:`BAUD_TOLERANCE` of ``measured``, the nearest first (ties:
    the commoner first)."""
    near = [baud for baud in STANDARD_BAUDS if abs(baud - measured) / baud < BAUD_TOLERANCE]
    return sorted(near, key=lambda baud: (round(abs(baud - measured) / baud, 3), STANDARD_BAUDS.index(baud)))


def decode_transitions(times_s: npt.NDArray[np.float64], levels: npt.NDArray[np.bool_], line: CharacterShape,
                       *, inverted: bool = False) -> UartCharacters:
    """UART characters of a line given as its transitions (``levels[i]`` from ``times_s[i]`` on,
    the first row the level where the recording starts), as a logic analyzer exports them
    instead of samples. The rules are :class:`UartDecoder`'s, read on times; the characters'
    ``start_samples`` and ``end_samples`` are in seconds."""
    if len(times_s) < 2:
        return _empty()
    level = levels != inverted
    width = 1.0 / line.baud
    slots = 1 + line.data_bits + (0 if line.parity is Parity.NONE else 1) + line.stop_bits

    def at(moments: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        return np.asarray(level[np.maximum(np.searchsorted(times_s, moments, "right") - 1, 0)], np.bool_)

    edges = times_s[1:][level[:-1] & ~level[1:]]
    stop_middle = (slots - line.stop_bits + 0.5) * width
    # Every edge's character is complete: the recording's last level holds on after its last row.
    start_ok = ~at(edges + width / 2)
    resume = np.where(start_ok, edges + stop_middle, edges + width / 2)
    following = np.searchsorted(edges, resume, "left")
    starts = edges[_chain(following, start_ok, len(edges))]
    return read_characters(line, lambda slot: at(starts + (slot + 0.5) * width), starts, starts + slots * width)
