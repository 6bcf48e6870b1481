import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from decoders.crc import crc16_modbus, crc16_modbus_reference, crc_bytes, crc_ok, crc_ok_many
from tests.conftest import load_manual_frames

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
