"""USS telegrams on a NORD bus: recognised, paired and decoded instead of reported as CRC errors."""

from __future__ import annotations

import struct
from functools import reduce
from operator import xor

from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import ChunkBatch, TimingQuality
from decoders.framing.best_parse import parse_segment
from decoders.framing.programme import Context
from decoders.line import LineSettings
from decoders.message import Message, Role
from decoders.pipeline import decode
from decoders.uss import parse_uss, uss_length
from sniffer.profiles_io import profile_book

LINE = LineSettings.parse("9600 8E1")
MODBUS_WRITE = bytes.fromhex("08100C8100030603E807D00BB8F5DF")
MODBUS_ANSWER = bytes.fromhex("08100C810003D3E9")


def telegram(adr: int, words: list[int]) -> bytes:
    body = bytes([0x02, 2 * len(words) + 2, adr]) + struct.pack(f">{len(words)}H", *words)
    return body + bytes([reduce(xor, body, 0)])


ASK = telegram(5, [0x1066, 0, 0, 0, 0x047E, 0x2000])  # PPO 1: PKW (P102 read) + STW, SW1
ANSWER = telegram(5, [0x1066, 0, 0, 500, 0x0B31, 0x1FFF])


def run(frames: list[bytes], gap_ns: int, *profiles: str) -> list[Message]:
    chunks = list(exact_chunks([Transmission(f, gap_ns) for f in frames], LINE, 0))
    return list(decode([ChunkBatch.from_chunks(chunks)], LINE, TimingQuality.EXACT, profile_book(list(profiles), [])))


def test_telegram_layout() -> None:
    assert uss_length(ASK) == 16
    assert uss_length(ASK[:-1] + bytes([ASK[-1] ^ 1])) is None  # BCC wrong
    assert uss_length(bytes([0x02, 0x07]) + ASK[2:]) is None  # not a NORD PPO length
    decoded = parse_uss(ANSWER)
    fields = (decoded.address, decoded.ak, decoded.pnu, decoded.pwe, decoded.pzd)
    assert fields == (5, 1, 102, (0, 500), (0x0B31, 0x1FFF))


def test_uss_and_modbus_on_one_line() -> None:
    for gap in (2_000_000, 20_000_000):  # answers inside t3.5, and well apart
        messages = run([ASK, ANSWER, MODBUS_WRITE, MODBUS_ANSWER, ASK, ANSWER], gap, "nord-sk")
        assert [m.frame.protocol for m in messages] == [1, 1, 0, 0, 1, 1]
        assert all(m.frame.crc_ok for m in messages)
        assert [m.role for m in messages[:2]] == [Role.REQUEST, Role.RESPONSE]
        assert messages[1].request_index == 0 and messages[5].request_index == 4
        assert messages[0].summary.endswith("STW = 16#047E shutdown (to ready to switch on)")
        assert messages[1].summary.endswith("ZSW = 16#0B31 ready to switch on (Einschaltbereit)")


def test_uss_record_in_jsonl(cli: object, tmp_path: object) -> None:
    from pathlib import Path

    capture = Path(str(tmp_path)) / "nord.log"
    lines = ["# rtu-capture v1", "# line: 9600 8E1", "# timing: exact"]
    t = 1_700_000_000_000_000_000
    for frame in (ASK, ANSWER):
        t += 30_000_000
        lines.append(f"{t // 10**9}.{t % 10**9:09d} {frame.hex(' ')}")
    capture.write_text("\n".join(lines) + "\n")
    records = cli("analyze", str(capture), "--format", "jsonl", "--profile", "nord-sk").jsonl()  # type: ignore[operator]
    frames = [r for r in records if r["kind"] == "frame"]
    assert [(f["protocol"], f["role"], f["slave"], f["function"], f["crc_ok"]) for f in frames] == [
        ("uss", "request", 5, None, True), ("uss", "response", 5, None, True)]
    assert records[-1]["crc_errors"] == 0


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=60))
def test_noise_is_not_taken_for_uss_next_to_modbus(noise: bytes) -> None:
    """Modbus frames around random bytes stay found; USS only where a telegram really is."""
    data = MODBUS_ANSWER + noise + MODBUS_ANSWER
    pieces = list(parse_segment(data, Context(closed=True, timed=True)).pieces)
    assert (pieces[0].start, pieces[0].end, pieces[0].crc_ok) == (0, len(MODBUS_ANSWER), True)
    assert (pieces[-1].end - pieces[-1].start, pieces[-1].crc_ok) == (len(MODBUS_ANSWER), True)
    for piece in pieces:
        if piece.protocol == 1:
            assert uss_length(data[piece.start : piece.end]) == piece.end - piece.start
