"""Which way up a logic analyzer's probe reads: a UART line idles high, but a probe on an
inverted line (an RS485 transceiver's output wired the other way, a line held low when the
recording started) idles low.

The level at the first sample was the whole rule, and a line that happened to be low there (a
character or a break under way when the analyzer started) was read inverted: a clean bus became
noise and framing errors. That level is now where the choice starts, and the evidence overrules
it: the line is decoded both ways with the line settings read with, and the other way wins where
the first way's characters have clearly the larger share of framing errors (at least twice the
other's, and five points more: a line read upside down misses most stop bits, while a few
framing errors on a real line, or parity errors made on purpose, say nothing of its polarity),
or where the first way reads no character and the other does.
``--invert``/``--no-invert`` force it. What was chosen against the first sample's level, and any
line read inverted, is said in a warning.
"""

from __future__ import annotations

from collections.abc import Callable

from decoders.uart import UartCharacters


def errors_in(characters: UartCharacters) -> int:
    """The characters with a framing or a parity error."""
    return int((characters.framing_errors | characters.parity_errors).sum())


def _framing_share(characters: UartCharacters) -> float:
    """The share of characters with a framing error (1: none read)."""
    return float(characters.framing_errors.mean()) if len(characters) else 1.0


#: How much larger the first way's share of framing errors must be for the other way to win:
#: at least this many times the other's, and this much more.
OVERRULED_BY, OVERRULED_PLUS = 2.0, 0.05


def chosen_polarity(decode: Callable[[bool], UartCharacters], *, starts_low: bool, forced: bool | None,
                    name: str) -> tuple[bool, str | None]:
    """Whether to read a line inverted, and a warning to give (``None``: nothing to say):
    ``decode(inverted)`` decodes the samples looked at; ``forced``: ``--invert``/``--no-invert``;
    ``name``: the line, as messages name it (``probe 0``)."""
    if forced is not None:
        return forced, None
    first, other = decode(starts_low), decode(not starts_low)
    first_share, other_share = _framing_share(first), _framing_share(other)
    overruled = first_share >= OVERRULED_BY * other_share + OVERRULED_PLUS
    chosen = not starts_low if overruled else starts_low
    chosen_read, other_read = (other, first) if overruled else (first, other)
    counts = (f"{errors_in(chosen_read)} of {len(chosen_read)} characters with an error against "
              f"{errors_in(other_read)} of {len(other_read)}")
    if chosen and overruled:
        return True, f"{name} read inverted (it idles low): {counts} as it is; --no-invert reads it as it is"
    if chosen:
        return True, (f"{name} read inverted: it is low where the recording starts ({counts} as it is); "
                      "--no-invert reads it as it is")
    if overruled:
        return False, (f"{name} is low where the recording starts, yet reads as it is: {counts} inverted; "
                       "--invert reads it inverted")
    return False, None
