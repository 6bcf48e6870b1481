"""Regenerate the shipped sample captures, reproducibly (fixed seed, fixed start time).

    python captures/make_samples.py [OUTPUT_DIR]

atv71-plc-poll: a PLC polls Altivar 71 drives at 19200 8E1 with the manual's own
example frames (docs: device-digest.md section 7): drive 2 (FC3, FC6, FC16, FC43),
drive 20 (the FC23 scanner exchange), drive 4 (writing the read-only ETA ->
exception 04; FC8 echo) and drive 12 (reading protected parameters -> 16#8000
and exception 02). Field faults are mixed in: one response with a bit error, a
retry after it, a response with a 2-character pause inside, a drive that answers
after one character, a transmitter turn-off glitch, and a drive 3 that never
answers. Recorded exactly (a hardware tap).

atv71-plc-poll-usb: the same wire traffic as a PC records it through a USB-RS485
adapter with the default 16 ms latency timer: bytes in bursts, host times.
"""

from __future__ import annotations

import json
import random
import struct
import sys
from collections.abc import Callable
from functools import reduce
from operator import xor
from pathlib import Path

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.line import LineSettings
from sniffer.io.registry import open_writer

# The wire models live with the benchmarks, in the checkout this script is part of.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.wire_synthesis import Transmission, exact_chunks, usb_adapter_chunks

HERE = Path(__file__).resolve().parent
T0_NS = 1_700_000_000_000_000_000
SEED = 71
LINE = LineSettings.parse("19200 8E1")
MS = 1_000_000


def manual_frames() -> dict[str, bytes]:
    doc = json.loads((HERE / "manual-frames.json").read_text())
    return {f["id"]: bytes.fromhex(f["hex"]) for f in doc["frames"]}


#: NMA1-8 and NCA1-6 of the manual's scanner example: ETA, RFRD, LCR, OTR, ULN, THD, THR, LFT
#: are read into NM1-8; NC1-6 are written to CMD, LFRD, HSP, LSP, ACC, DEC.
SCANNER_INPUTS = (3201, 8604, 3204, 3205, 3207, 3209, 9630, 7121)
SCANNER_OUTPUTS = (8501, 8602, 3104, 3105, 9001, 9002)


def with_crc(body: bytes) -> bytes:
    return body + crc_bytes(body)


def flip_bit(frame: bytes, position: int, bit: int) -> bytes:
    damaged = bytearray(frame)
    damaged[position] ^= 1 << bit
    return bytes(damaged)


def atv71_plc_poll() -> list[Transmission]:
    """Five PLC cycles of about 100 ms; drive turnaround 2-6 ms."""
    frames = manual_frames()
    rng = random.Random(SEED)
    absent_drive = with_crc(bytes.fromhex("03030C1E0004"))
    out: list[Transmission] = []

    def master(frame: bytes, pause_ms: float | None = None, gaps: dict[int, int] | None = None) -> None:
        idle = (pause_ms if pause_ms is not None else rng.uniform(4.0, 9.0)) * MS
        out.append(Transmission(frame, int(idle), gaps or {}))

    def drive(frame: bytes, gaps: dict[int, int] | None = None, turnaround_ms: float | None = None) -> None:
        idle = turnaround_ms if turnaround_ms is not None else rng.uniform(2.0, 6.0)
        out.append(Transmission(frame, int(idle * MS), gaps or {}))

    def glitch() -> None:
        # A driver releasing the bus: one 0x00 half a character after the frame.
        out.append(Transmission(b"\x00", round(LINE.char_time_ns / 2)))

    master(frames["A11"], pause_ms=0)  # identify drive 2 once at start
    drive(frames["A12"])
    # Read drive 20's communication scanner set-up (the manual's example, ATV71:1393-1459).
    for address, values in ((12701, SCANNER_INPUTS), (12721, SCANNER_OUTPUTS)):
        master(with_crc(struct.pack(">BBHH", 20, 3, address, len(values))))
        drive(with_crc(struct.pack(f">BBB{len(values)}H", 20, 3, 2 * len(values), *values)))
    for cycle in range(5):
        master(frames["A1"], pause_ms=None if cycle else 20)
        if cycle == 2:
            drive(flip_bit(frames["A2"], 6, 3))  # bit error on the line
            master(frames["A1"], pause_ms=30)  # the PLC repeats
        drive(frames["A2"])
        master(frames["A13"])
        # A 2-character pause inside the response on cycle 3 (a slow drive UART);
        # on cycle 4 the drive answers after 1 character, well inside t3.5.
        drive(
            frames["A14"],
            gaps={9: round(2 * LINE.char_time_ns)} if cycle == 3 else None,
            turnaround_ms=0.6 if cycle == 4 else None,
        )
        master(frames["A17"])
        drive(frames[("A18", "A19", "A20", "A18", "A18")[cycle]])
        if cycle == 4:
            glitch()
        master(absent_drive)  # drive 3 is configured in the PLC but missing
        if cycle == 1:
            master(frames["A7"], pause_ms=1000)  # set ACC after the timeout
            drive(frames["A7"])
            master(frames["A9"])
            drive(frames["A10"])
        if cycle == 3:
            master(frames["A15"], pause_ms=1000)
            drive(frames["A16"])
            master(frames["A8"])
            drive(frames["A8"])
    return out


def atv312_setup() -> list[Transmission]:
    """A commissioning PC sets up an Altivar 312 (slave 2) with the ATV312 manual's frames."""
    frames = manual_frames()
    rng = random.Random(SEED + 312)
    out: list[Transmission] = []

    def pair(ask: bytes, answer: bytes | None) -> None:
        out.append(Transmission(ask, int(rng.uniform(8, 20) * MS)))
        if answer is not None:
            out.append(Transmission(answer, int(rng.uniform(2, 6) * MS)))

    pair(frames["B4"], frames["B5"])  # identification: the drive says it is an ATV31...
    pair(frames["B1"], frames["B2"])  # SFr, tFr, HSP, LSP
    pair(frames["B3"], frames["B3"])  # ACC = 13 s
    pair(frames["B6"], frames["B7"])  # the manual's FC 16 pair, with its wrong CRCs
    pair(with_crc(struct.pack(">BBHH", 2, 3, 3102, 40)), with_crc(bytes.fromhex("028302")))  # 40 > 29 words
    pair(with_crc(struct.pack(">BBHH", 2, 4, 3102, 2)), with_crc(bytes.fromhex("028401")))  # FC 4 unsupported
    pair(frames["B1"], frames["B2"])
    return out


def nord_uss() -> list[Transmission]:
    """A PLC runs a NORD SK drive (address 5) over USS, PPO 1, while a tool writes process data
    over Modbus RTU to a NORD SK 54xE (slave 8) on the same line (NORD BU 0050)."""
    rng = random.Random(SEED + 50)
    out: list[Transmission] = []
    # STW steps: ready to switch on (047E), switch on (047F), operation (047F + enable); ZSW answers.
    steps = [(0x047E, 0x0B31), (0x047F, 0x0B33), (0x047F, 0x0B37), (0x047F, 0x0B37)]
    for cycle, (control, status) in enumerate(steps * 2):
        setpoint = 0x2000 if cycle > 1 else 0
        out.append(Transmission(uss_telegram(5, [0x1066, 0, 0, 0, control, setpoint]), int(rng.uniform(30, 40) * MS)))
        out.append(Transmission(uss_telegram(5, [0x1066, 0, 0, 300, status, setpoint]), int(rng.uniform(2, 8) * MS)))
        if cycle == 3:
            frames = manual_frames()
            out.append(Transmission(frames["N3req"], int(30 * MS)))
            out.append(Transmission(frames["N3res"], int(4 * MS)))
    return out


def uss_telegram(adr: int, words: list[int]) -> bytes:
    """STX, LGE, ADR, the words, BCC (XOR of all bytes before it)."""
    body = bytes([0x02, 2 * len(words) + 2, adr]) + struct.pack(f">{len(words)}H", *words)
    return body + bytes([reduce(xor, body, 0)])


def xbt_hmi() -> list[Transmission]:
    """A Magelis XBT polls %MW20-24 of the Controller Inside card of an ATV71 (slave 54, the manual's
    frames), writes %MW100, and retries a terminal (slave 7) that does not answer. 19200 8N1, which
    the XBT allows 'contrary to the standard'."""
    frames = manual_frames()
    rng = random.Random(SEED + 3986)
    out: list[Transmission] = []
    write = with_crc(struct.pack(">BBHHB2H", 54, 16, 100, 2, 4, 1234, 0))
    absent = with_crc(struct.pack(">BBHH", 7, 3, 0, 10))
    for cycle in range(4):
        out.append(Transmission(frames["A3"], int(rng.uniform(90, 110) * MS)))
        out.append(Transmission(frames["A4"], int(rng.uniform(2, 5) * MS)))
        if cycle == 1:
            out.append(Transmission(write, int(10 * MS)))
            out.append(Transmission(with_crc(struct.pack(">BBHH", 54, 16, 100, 2)), int(3 * MS)))
        if cycle == 2:
            out.append(Transmission(absent, int(10 * MS)))
            out.append(Transmission(absent, int(3000 * MS)))  # XBT timeout 30 x 100 ms, then its retry
    return out


def xbt_floats() -> list[Transmission]:
    """A Magelis XBT polls the 32-bit variables of its project on slave 54: %MF30 (a tank level)
    and %MF32 (a flow), IEEE 754 floats, and %MD34 (pump starts), each low word first at %MWi and
    high word at %MWi+1 (XBT:1097-1102); it reads %MF30 once alone by its high word, %MW31 (half
    of a float), and writes the level's setpoint %MF36. 19200 8N1."""
    rng = random.Random(SEED + 1097)
    out: list[Transmission] = []
    level, flow, starts = 62.5, 12.0, 1407
    for cycle in range(6):
        level += rng.uniform(-0.4, 0.4)
        flow += rng.uniform(-0.2, 0.2)
        starts += cycle == 3
        words = [*_low_first(struct.pack(">f", level)), *_low_first(struct.pack(">f", flow)),
                 *_low_first(struct.pack(">I", starts))]
        out.append(Transmission(with_crc(struct.pack(">BBHH", 54, 3, 30, 6)), int(rng.uniform(90, 110) * MS)))
        out.append(Transmission(with_crc(struct.pack(">BBB6H", 54, 3, 12, *words)), int(rng.uniform(2, 5) * MS)))
        if cycle == 2:
            out.append(Transmission(with_crc(struct.pack(">BBHH", 54, 3, 31, 1)), int(10 * MS)))
            out.append(Transmission(with_crc(struct.pack(">BBBH", 54, 3, 2, words[1])), int(3 * MS)))
        if cycle == 4:
            setpoint = _low_first(struct.pack(">f", 70.0))
            out.append(Transmission(with_crc(struct.pack(">BBHHB2H", 54, 16, 36, 2, 4, *setpoint)), int(10 * MS)))
            out.append(Transmission(with_crc(struct.pack(">BBHH", 54, 16, 36, 2)), int(3 * MS)))
    return out


def _low_first(value: bytes) -> list[int]:
    """A 32-bit value's two registers as the XBT lays them: low word first."""
    high, low = struct.unpack(">HH", value)
    return [low, high]


def exact(transmissions: list[Transmission], line: LineSettings = LINE) -> list[Chunk]:
    return list(exact_chunks(transmissions, line, T0_NS))


def through_usb_adapter(transmissions: list[Transmission]) -> list[Chunk]:
    return usb_adapter_chunks(exact(transmissions), LINE, latency_ns=16 * MS, seed=SEED)


POLL_NOTE = "Sample: PLC polling Altivar 71 drives 2, 20, 4, 12 (manual example frames), 19200 8E1, synthetic"
XBT_LINE = LineSettings.parse("19200 8N1")
SAMPLES: dict[str, tuple[Callable[[], list[Chunk]], TimingQuality, LineSettings, str]] = {
    "atv71-plc-poll": (lambda: exact(atv71_plc_poll()), TimingQuality.EXACT, LINE, POLL_NOTE),
    "atv71-plc-poll-usb": (
        lambda: through_usb_adapter(atv71_plc_poll()),
        TimingQuality.HOST,
        LINE,
        POLL_NOTE + ", recorded through a USB adapter (16 ms latency timer, model)",
    ),
    "atv312-setup": (
        lambda: exact(atv312_setup()), TimingQuality.EXACT, LINE,
        "Sample: a PC sets up an Altivar 312 (slave 2) with the ATV312 manual's frames, 19200 8E1, synthetic",
    ),
    "nord-uss": (
        lambda: exact(nord_uss()), TimingQuality.EXACT, LINE,
        "Sample: USS (NORD SK, address 5, PPO 1) and Modbus RTU (slave 8) on one line, 19200 8E1, synthetic",
    ),
    "xbt-hmi": (
        lambda: exact(xbt_hmi(), XBT_LINE), TimingQuality.EXACT, XBT_LINE,
        "Sample: a Magelis XBT polls %MW20-24 on slave 54 and retries an absent slave 7, 19200 8N1, synthetic",
    ),
    "xbt-floats": (
        lambda: exact(xbt_floats(), XBT_LINE), TimingQuality.EXACT, XBT_LINE,
        "Sample: a Magelis XBT polls %MF30, %MF32 and %MD34 (low word first) on slave 54, 19200 8N1, synthetic",
    ),
}


def write_samples(directory: Path) -> list[Path]:
    written = []
    for name, (build, timing, line, note) in SAMPLES.items():
        info = CaptureInfo(line, timing, (note, f"generated by captures/make_samples.py, seed {SEED}"))
        batch = ChunkBatch.from_chunks(build())
        for suffix in (".log", ".mcap"):
            path = directory / f"{name}{suffix}"
            writer = open_writer(str(path), info)
            writer.write_batch(batch)
            writer.close()
            written.append(path)
    return written


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE
    for path in write_samples(target):
        print(path)
