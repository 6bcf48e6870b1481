"""Golden decoded output for every complete example frame of the manuals.

The expected output lives in tests/golden/manual-frames.decoded.json; after a
deliberate change, regenerate it with RTUSNIFF_REGENERATE_GOLDEN=1 and review the diff.
"""

from __future__ import annotations

import dataclasses
import json
import os
from typing import Any

import pytest

from decoders.modbus.pdu import parse_pdu
from tests.conftest import ROOT, load_manual_frames

GOLDEN = ROOT / "tests" / "golden" / "manual-frames.decoded.json"


def plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"type": type(value).__name__} | fields
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, tuple | list):
        return [plain(v) for v in value]
    return value


def decoded() -> dict[str, Any]:
    out: dict[str, Any] = {}
    for frame in load_manual_frames():
        adu = bytes.fromhex(frame["hex"])
        one_way = {"request": [True], "response": [False], "exception": [False]}
        directions = one_way.get(frame["direction"], [True, False])
        for is_request in directions:
            pdu = parse_pdu(adu, is_request=is_request)
            key = f"{frame['id']} {'request' if is_request else 'response'}"
            out[key] = {"hex": frame["hex"], "pdu": plain(pdu), "summary": pdu.summary()}
    return out


def test_manual_frames_decode_as_golden() -> None:
    current = decoded()
    if os.environ.get("RTUSNIFF_REGENERATE_GOLDEN"):
        GOLDEN.write_text(json.dumps(current, indent=1, ensure_ascii=False) + "\n")
    expected = json.loads(GOLDEN.read_text())
    assert current.keys() == expected.keys()
    for key in expected:
        assert current[key] == expected[key], key


@pytest.mark.parametrize(
    ("frame_id", "words"),
    [
        ("A2", "HR = 0028 0258 01F4 0000"),
        ("A12", "ProductCode='ATV71HU15M3'"),
        ("A13", "read HR 12741..12748 (8), write HR 12761..12766"),
        ("A16", "exception 04 Server Device Failure"),
        ("A20", "exception 02 Illegal Data Address"),
        ("A8", "diagnostics 00 Return Query Data (echo), data 31 32"),
    ],
)
def test_key_summaries(frame_id: str, words: str) -> None:
    assert any(k.startswith(f"{frame_id} ") and words in v["summary"] for k, v in decoded().items())
