"""Golden decoded output for every complete example frame of the manuals.

The expected output lives in tests/golden/manual-frames.decoded.json; after a
deliberate change, regenerate it with RTUSNIFF_REGENERATE_GOLDEN=1 and review the diff.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

import pytest

from decoders.modbus.codecs import parse_pdu
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


PROFILED = ROOT / "tests" / "golden" / "manual-exchanges.profiled.json"
#: The manuals' exchanges (request, answer), decoded with the profile of their device.
EXCHANGES = {
    "atv71": [("A11", "A12"), ("A1", "A2"), ("A3", "A4"), ("A5", "A6"), ("A7", "A7"), ("A8", "A8"), ("A9", "A10"),
              ("A13", "A14"), ("A15", "A16"), ("A17", "A18"), ("A17", "A19"), ("A17", "A20")],
    "atv312": [("B4", "B5"), ("B1", "B2"), ("B3", "B3"), ("B6", "B7")],
    "nord-sk": [("N1r", "N1r"), ("N3req", "N3res")],
}


def profiled() -> dict[str, Any]:
    from benchmarks.wire_synthesis import Transmission, exact_chunks
    from decoders.capture import ChunkBatch, TimingQuality
    from decoders.line import LineSettings
    from decoders.pipeline import decode
    from sniffer.profiles_io import profile_book

    frames = {f["id"]: bytes.fromhex(f["hex"]) for f in load_manual_frames()}
    line = LineSettings.parse("19200 8E1")
    out: dict[str, Any] = {}
    for profile, exchanges in EXCHANGES.items():
        sequence = [frames[i] for pair in exchanges for i in pair]
        chunks = list(exact_chunks([Transmission(f, 50_000_000) for f in sequence], line, 0))
        book = profile_book([profile], [])
        messages = list(decode([ChunkBatch.from_chunks(chunks)], line, TimingQuality.EXACT, book))
        ids = [i for pair in exchanges for i in pair]
        for position, (frame_id, message) in enumerate(zip(ids, messages, strict=True)):
            out[f"{profile} {position:02d} {frame_id}"] = {
                "role": message.role.value,
                "summary": message.summary,
                "params": [[p.address, p.code, p.raw, p.value, p.unit] for p in message.params],
                "remarks": list(message.remarks),
            }
    return out


def check_golden(path: Path, current: dict[str, Any]) -> None:
    """``current`` equals the golden file, entry by entry (regenerated on request)."""
    if os.environ.get("RTUSNIFF_REGENERATE_GOLDEN"):
        path.write_text(json.dumps(current, indent=1, ensure_ascii=False) + "\n")
    expected = json.loads(path.read_text())
    assert current.keys() == expected.keys()
    for key in expected:
        assert current[key] == expected[key], key


def test_manual_exchanges_with_profiles_as_golden() -> None:
    check_golden(PROFILED, profiled())


def test_manual_frames_decode_as_golden() -> None:
    check_golden(GOLDEN, decoded())


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
