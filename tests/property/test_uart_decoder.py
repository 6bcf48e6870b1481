"""Hypothesis: the UART decoder reads back any characters written on a sampled line -- every
format sigrok's decoder knows (5-9 data bits, five parities, 1, 1.5 or 2 stop bits, inverted),
fed whole or in pieces, as samples or as transitions -- and marks a wrong parity or stop bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.line import Parity
from decoders.uart import CharacterFormat, UartDecoder, decode_transitions

FORMATS = st.builds(CharacterFormat, baud=st.sampled_from([9600, 19200, 115200]), data_bits=st.integers(5, 9),
                    parity=st.sampled_from(list(Parity)), stop_bits=st.sampled_from([1, 1.5, 2]))


def parity_bit(value: int, parity: Parity) -> int:
    ones = bin(value).count("1") % 2
    return {Parity.EVEN: ones, Parity.ODD: 1 - ones, Parity.MARK: 1, Parity.SPACE: 0, Parity.NONE: 0}[parity]


def waveform(form: CharacterFormat, per_bit: int, characters: list[tuple[int, int, bool, bool]]
             ) -> tuple[np.ndarray, list[float]]:
    """Idle-high samples of ``characters`` (value, idle bits before, parity wrong, stop low) at
    ``per_bit`` samples a bit, and each character's end in samples."""
    levels, ends, at = [], [], 0.0
    for value, idle, bad_parity, stop_low in characters:
        pieces = [(1, idle + 1), (0, 1)] + [((value >> k) & 1, 1) for k in range(form.data_bits)]
        if form.parity is not Parity.NONE:
            pieces.append((parity_bit(value, form.parity) ^ bad_parity, 1))
        pieces.append((0 if stop_low else 1, form.stop_bits))
        for level, length in pieces:
            count = round((at + length) * per_bit) - round(at * per_bit)
            levels.append(np.full(count, level, np.bool_))
            at += length
        ends.append(at * per_bit)
    levels.append(np.ones(3 * per_bit, np.bool_))
    return np.concatenate(levels), ends


@st.composite
def lines(draw: st.DrawFn) -> tuple[CharacterFormat, int, list[tuple[int, int, bool, bool]]]:
    form = draw(FORMATS)
    per_bit = draw(st.integers(6, 24))
    values = st.integers(0, (1 << form.data_bits) - 1)
    characters = draw(st.lists(st.tuples(values, st.integers(0, 4), st.just(False), st.just(False)), min_size=1,
                               max_size=30))
    return form, per_bit, characters


@settings(max_examples=200, deadline=None)
@given(lines(), st.booleans(), st.data())
def test_characters_read_back_whole_or_in_pieces(line: tuple[CharacterFormat, int, list[tuple[int, int, bool, bool]]],
                                                 inverted: bool, data: st.DataObject) -> None:
    form, per_bit, characters = line
    samples, ends = waveform(form, per_bit, characters)
    samples = samples != inverted
    rate = float(form.baud * per_bit)
    whole = UartDecoder(form, rate, inverted).feed(samples)
    assert whole.values.tolist() == [value for value, *_ in characters]
    assert not whole.framing_errors.any() and not whole.parity_errors.any()
    assert np.all(np.abs(whole.end_samples - ends) <= 1.0)
    cuts = sorted(data.draw(st.lists(st.integers(1, len(samples) - 1), max_size=6)))
    decoder, pieces = UartDecoder(form, rate, inverted), []
    for begin, end in zip([0, *cuts], [*cuts, len(samples)], strict=True):
        pieces.append(decoder.feed(samples[begin:end]))
    assert np.concatenate([p.values for p in pieces]).tolist() == whole.values.tolist()
    changes = np.flatnonzero(samples[1:] != samples[:-1]) + 1
    moments = np.concatenate([[0], changes]).astype(np.float64) / rate
    timed = decode_transitions(moments, samples[np.concatenate([[0], changes])], form, inverted=inverted)
    assert timed.values.tolist() == whole.values.tolist()


@settings(max_examples=150, deadline=None)
@given(FORMATS.filter(lambda f: f.parity is not Parity.NONE), st.integers(6, 24), st.data())
def test_a_wrong_parity_or_stop_bit_is_marked(form: CharacterFormat, per_bit: int, data: st.DataObject) -> None:
    count = data.draw(st.integers(1, 12))
    values = data.draw(st.lists(st.integers(0, (1 << form.data_bits) - 1), min_size=count, max_size=count))
    parity = data.draw(st.lists(st.booleans(), min_size=count, max_size=count))
    # A low stop bit runs into the next start bit: the next character starts after idle.
    stop = data.draw(st.lists(st.booleans(), min_size=count, max_size=count))
    characters = [(v, 3, p, s) for v, p, s in zip(values, parity, stop, strict=True)]
    samples, _ = waveform(form, per_bit, characters)
    got = UartDecoder(form, float(form.baud * per_bit)).feed(samples)
    assert got.values.tolist() == values
    assert got.parity_errors.tolist() == parity
    assert got.framing_errors.tolist() == stop
