"""Plain numbers named in arrays (:class:`decoders.profiles.naming.PlainNumbers`) are what a
register's namer makes of the same raw word, for every register of every shipped profile; and
a batch of drives' traffic names them so where an output asks for it."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.modbus.annotate import Annotator
from decoders.profiles.apply import ProfileApplier
from decoders.profiles.naming import AddressNamer, _rounded_products
from sniffer.profiles_io import profile_book, shipped_profiles
from tests.property.test_annotation_cache import adu, matched

#: Raw words where the rules change: around zero, the sign bit, the top; and every word of a
#: register of each kind below.
EDGES = [*range(0, 64), 0x7FFE, 0x7FFF, 0x8000, 0x8001, 0x8002, 0xFFFE, 0xFFFF]


def _namers() -> list[tuple[str, AddressNamer, bool]]:
    """Every register of every shipped profile (and one no parameter names), as reported and as
    written; and whether it is the first of its sign and scale (its every raw word is checked)."""
    namers, kinds = [], set()
    for name, profile in sorted(shipped_profiles().items()):
        for reported in (True, False):
            for address, parameter in [*sorted(profile.parameters.items()), (40000, None)]:
                # A register no parameter names is labelled by its address (as XBT profiles spell theirs).
                label = ("%MW40000", "440001") if parameter is None else (parameter.code, parameter.name)
                kind = (False, 1.0) if parameter is None else (parameter.signed, parameter.scale)
                namers.append((f"{name}:{address}:{'reported' if reported else 'written'}",
                               AddressNamer(profile, address, label, parameter, reported=reported, learns=False),
                               kind not in kinds))
                kinds.add(kind)
    return namers


NAMERS = _namers()


@pytest.mark.parametrize(("where", "namer", "every_word"), NAMERS, ids=[where for where, _, _ in NAMERS])
def test_plain_numbers_are_what_the_namer_makes(where: str, namer: AddressNamer, every_word: bool) -> None:
    plain = namer.plain_numbers()
    parameter = namer.parameter
    if parameter is not None and parameter.bitfield is not None:
        assert plain is None  # a state word's values are texts
        return
    assert plain is not None
    words = set(plain.words.tolist())
    for raw in range(0x10000) if every_word else EDGES + sorted(words):
        made = namer.make(raw)
        if raw in words:
            assert isinstance(made[0].value, str) or not made[0].available, (where, raw)
            continue
        assert plain.param(raw, float(plain.value[raw])) == made, (where, raw)
        assert type(made[0].value) is (int if plain.integral else float), (where, raw)


def test_drives_traffic_names_its_plain_numbers_in_arrays_when_asked() -> None:
    """Not vacuous: reads of scaled, signed and enumerated registers of an ATV71 leave their
    plain numbers in arrays (HSP at a tenth, LCR signed, the unnamed register between), the
    enumerated and marked words named values; without ``numbers`` every value is one."""
    s = b"\x01"
    traffic = [adu(s, b"\x03", struct.pack(">HH", 3104, 1)), adu(s, b"\x03\x02", struct.pack(">H", 438)),
               adu(s, b"\x03", struct.pack(">HH", 3203, 2)), adu(s, b"\x03\x04", struct.pack(">HH", 7, 0xFFF6)),
               adu(s, b"\x03", struct.pack(">HH", 8401, 2)), adu(s, b"\x03\x04", struct.pack(">HH", 3, 0x8000))]
    (batch,) = [batch for batch in matched(traffic) if len(batch)]
    for numbers in (True, False):
        annotator = Annotator(ProfileApplier(profile_book(["atv71"], [])))
        reads = annotator.annotate_columnar(batch, numbers=numbers).columnar
        assert reads is not None and reads.names is not None and len(reads) == 6
        texts = reads.summaries(batch.frames.data)
        assert texts[1] == "HR = 01B6 (1 registers): HSP = 43.8 Hz"
        assert texts[3] == "HR = 0007 FFF6 (2 registers): LCR = -10"
        assert texts[5] == ("HR = 0003 8000 (2 registers): CHCF = 16#0003 I/O profile, "
                            "COP = 16#8000 non-existent or protected parameter")
        numbered = reads.names.numbers
        if not numbers:
            assert numbered is None
            continue
        assert numbered is not None
        assert [(plain.code, raw, value) for plain, raw, value in zip(
            [numbered.registers[place] for place in numbered.register.tolist()], numbered.raw.tolist(),
            numbered.value.tolist(), strict=True)] == [("HSP", 438, 43.8), (None, 7, 7.0), ("LCR", 0xFFF6, -10.0)]
        assert all(param.raw in (None, 3, 0x8000) for param, _ in reads.names.table)


#: Scales of real parameters (tenths to thousandths, binary fractions, whole multiples), and ones
#: whose products land on a half of the sixth decimal (5e-7: every odd word) or past exact
#: integers in millionths (1e12), where numpy's rounding is not Python's and Python rounds.
SCALES = [0.1, 0.01, 0.001, 1e-4, 1e-6, 1e-7, 5e-7, 2.5e-7, 0.5, 0.25, 0.3, 1 / 3, 2 / 3, 0.15, 1.5, 10.0,
          1000.0, 0.0625, 60 / 65536, 0.123456789, 3.14159, 1e12]


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("signed", [False, True])
def test_rounded_products_are_pythons_round_for_every_raw_word(scale: float, signed: bool) -> None:
    words = np.arange(0x10000, dtype=np.int64)
    numbers = words - 0x10000 * ((words & 0x8000) != 0) if signed else words
    expected = np.array([round(number * scale, 6) for number in numbers.tolist()], np.float64)
    got = _rounded_products(numbers, scale)
    assert np.array_equal(got, expected)
    assert np.array_equal(np.signbit(got), np.signbit(expected))  # -0.0 where Python writes it


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=1e-9, max_value=1e6, allow_nan=False, allow_infinity=False), st.booleans())
def test_rounded_products_hold_for_any_scale(scale: float, signed: bool) -> None:
    numbers = np.arange(0x10000, dtype=np.int64) - (0x8000 if signed else 0)
    expected = np.array([round(number * scale, 6) for number in numbers.tolist()], np.float64)
    assert np.array_equal(_rounded_products(numbers, scale), expected)
