from itertools import pairwise

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given
from hypothesis import strategies as st

from decoders.crc import crc16_modbus, crc_bytes, crc_ok, crc_ok_many
from tests.conftest import load_manual_frames
from tests.oracles import crc16_modbus_reference, crc_ok_many_reference

MANUAL = load_manual_frames()


def test_check_value() -> None:
    assert crc16_modbus(b"123456789") == 0x4B37
    assert crc16_modbus_reference(b"123456789") == 0x4B37


@pytest.mark.parametrize("frame", MANUAL, ids=[f["id"] for f in MANUAL])
def test_every_manual_frame(frame: dict[str, object]) -> None:
    data = bytes.fromhex(str(frame["hex"]))
    assert crc_ok(data) is frame["crc_valid"]


def test_atv312_manual_crcs_are_wrong_and_fit_slave_f8(manual_frames: dict[str, bytes]) -> None:
    for frame_id, good_id in (("B6", "A9"), ("B7", "A10")):
        bad = manual_frames[frame_id]
        assert not crc_ok(bad)
        assert crc_bytes(bad[:-2]) == manual_frames[good_id][-2:]
        assert crc_bytes(b"\xf8" + bad[1:-2]) == bad[-2:]


@given(st.binary(max_size=300))
def test_fast_equals_reference(data: bytes) -> None:
    assert crc16_modbus(data) == crc16_modbus_reference(data)


def test_crc_ok_many_matches_single(manual_frames: dict[str, bytes]) -> None:
    frames = list(manual_frames.values())
    offsets = np.cumsum([0] + [len(f) for f in frames]).astype(np.int64)
    assert crc_ok_many(b"".join(frames), offsets).tolist() == [crc_ok(f) for f in frames]


@pytest.mark.parametrize("short", [b"", b"\x01", b"\x01\x02"])
def test_too_short_is_not_ok(short: bytes) -> None:
    assert not crc_ok(short)


@st.composite
def framed_runs(draw: st.DrawFn) -> tuple[bytes, npt.NDArray[np.int64]]:
    """Frames back to back, most of a few lengths (as on a bus) and CRC-valid, some damaged,
    some rare lengths, some too short, some long: every path of the lockstep check."""
    common = draw(st.lists(st.integers(3, 70), min_size=1, max_size=3))
    frames = []
    for _ in range(draw(st.integers(0, 120))):
        size = draw(st.sampled_from(common) | st.integers(0, 90))
        body = draw(st.binary(min_size=max(0, size - 2), max_size=max(0, size - 2)))
        frame = (body + crc_bytes(body))[:size] if size >= 2 else draw(st.binary(min_size=size, max_size=size))
        if frame and draw(st.integers(0, 4)) == 0:
            frame = frame[:-1] + bytes([frame[-1] ^ 0x10])
        frames.append(frame)
    offsets = np.cumsum([0, *map(len, frames)]).astype(np.int64)
    return b"".join(frames), offsets


@given(framed_runs())
def test_crc_ok_many_in_lockstep_matches_one_by_one(run: tuple[bytes, npt.NDArray[np.int64]]) -> None:
    data, offsets = run
    assert crc_ok_many(data, offsets).tolist() == crc_ok_many_reference(data, offsets).tolist()
    assert crc_ok_many(data, offsets).tolist() == [crc_ok(data[a:b]) for a, b in pairwise(offsets.tolist())]


@pytest.mark.parametrize("size", [0, 1, 2, 15, 16, 17, 63, 64, 65, 1000, 4096, 70_000, 300_001])
def test_prefix_registers_are_the_register_after_every_prefix(size: int) -> None:
    """Across the block widths prefix_registers chooses (16 to 128 bytes, by size) and their
    edges: the register after data[:k] for every k, as the plain table steps it."""
    from decoders.crc import CRC_TABLE, crc_ok_spans, prefix_registers

    data = np.random.default_rng(size).bytes(size)
    expected = [0xFFFF]
    for byte in data:
        expected.append((expected[-1] >> 8) ^ CRC_TABLE[(expected[-1] ^ byte) & 0xFF])
    registers = prefix_registers(data)
    assert registers.tolist() == expected
    if size >= 8:
        framed = data[:6] + crc_bytes(data[:6]) + data[8:]
        starts, lengths = np.array([0, 1]), np.array([8, 7])
        assert crc_ok_spans(prefix_registers(framed), starts, lengths).tolist() == [True, crc_ok(framed[1:8])]


@given(st.binary(min_size=0, max_size=400), st.data())
def test_crc_ok_lengths_are_the_spans_that_pass(data: bytes, draw: st.DataObject) -> None:
    """Every length at once, as crc_ok_spans finds them length by length; with frames planted
    at the start so that some lengths pass."""
    from decoders.crc import MAX_SPAN, crc_ok_lengths, crc_ok_spans, prefix_registers

    start = draw.draw(st.integers(0, len(data)))
    for planted in (0, 1):
        if planted and len(data) - start >= 6:
            cut = draw.draw(st.integers(start + 1, len(data) - 2))
            data = data[:cut] + crc_bytes(data[start:cut]) + data[cut + 2 :]
        registers = prefix_registers(data)
        shortest = draw.draw(st.integers(3, 8))
        longest = min(MAX_SPAN, len(data) - start, draw.draw(st.integers(0, MAX_SPAN)))
        lengths = np.arange(shortest, longest + 1, dtype=np.int64)
        expected = lengths[crc_ok_spans(registers, np.full(len(lengths), start, np.int64), lengths)].tolist()
        assert crc_ok_lengths(registers, start, shortest, longest) == expected
        assert all(crc16_modbus(data[start : start + n]) == 0 for n in expected)
