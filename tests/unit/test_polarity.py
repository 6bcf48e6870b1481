"""Which way up a logic analyzer's line reads (:func:`sniffer.io.polarity.chosen_polarity`)."""

from __future__ import annotations

import numpy as np

from decoders.uart import UartCharacters
from sniffer.io.polarity import chosen_polarity


def characters(count: int, framing: int) -> UartCharacters:
    """``count`` characters, the first ``framing`` of them with a framing error."""
    errors = np.arange(count) < framing
    times = np.arange(count, dtype=np.float64)
    return UartCharacters(np.zeros(count, np.uint16), times, times + 1, errors, np.zeros(count, np.bool_))


def decoding(as_is: UartCharacters, inverted: UartCharacters):  # type: ignore[no-untyped-def]
    return lambda upside_down: inverted if upside_down else as_is


def test_the_first_sample_s_level_holds_unless_clearly_overruled() -> None:
    # Starts high, reads cleanly: as it is, nothing said.
    assert chosen_polarity(decoding(characters(100, 0), characters(40, 40)), starts_low=False, forced=None,
                           name="probe 0") == (False, None)
    # Starts low, yet reads cleanly as it is: as it is, and said.
    inverted, said = chosen_polarity(decoding(characters(100, 0), characters(40, 38)), starts_low=True, forced=None,
                                     name="probe 0")
    assert not inverted and said is not None and "--invert reads it inverted" in said
    # A few framing errors either way on a real line say nothing: the first sample's level holds.
    assert chosen_polarity(decoding(characters(8, 3), characters(8, 2)), starts_low=False, forced=None,
                           name="probe 0") == (False, None)
    # Idles low for real: inverted, and said.
    inverted, said = chosen_polarity(decoding(characters(40, 40), characters(100, 0)), starts_low=False,
                                     forced=None, name="probe 0")
    assert inverted and said is not None and "--no-invert" in said


def test_a_tie_or_nothing_read_keeps_the_first_sample_s_level_and_forcing_wins() -> None:
    nothing = characters(0, 0)
    assert chosen_polarity(decoding(nothing, nothing), starts_low=False, forced=None, name="p") == (False, None)
    assert chosen_polarity(decoding(nothing, nothing), starts_low=True, forced=None, name="p")[0] is True
    assert chosen_polarity(decoding(characters(50, 50), characters(50, 0)), starts_low=False, forced=False,
                           name="p") == (False, None)
