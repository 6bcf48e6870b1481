"""Large realistic captures for benchmarks, reproducibly from a seed, as native MCAP captures.

    python -m benchmarks.generate_capture OUT.mcap [--frames 1000000] [--seed 1]
        [--line "115200 8N1"] [--timing exact|host|READ_LOOP] [--values random|steady]

A saturated line: a PLC polls 16 Altivar-like drives (ETA/RFRD reads by FC 3, CMD/LFRD writes by
FC 16, HSP by FC 6, the FC 23 scanner exchange, FC 43 identification now and then), with the
faults of real wires mixed in at fixed rates: exceptions 02 and 04, CRC bit errors, drives that do
not answer (timeouts, then a retry), 1.5-character pauses inside answers, drives that answer
faster than 3.5 characters, transmitter turn-off glitches. ``host`` records it as a PC does
through a USB adapter with a 16 ms latency timer. Written in pieces: memory stays small.

``--values random`` draws every speed and state word anew, so that almost no answer repeats
(the worst case for a decoder that decodes each distinct frame once); ``steady`` drives hold
their state and speed and change them now and then, as drives running a process do.
"""

from __future__ import annotations

import argparse
import random
import struct
from collections.abc import Iterator
from pathlib import Path

from benchmarks.read_loops import READ_LOOPS
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.line import LineSettings
from sniffer.io.registry import open_writer

T0_NS = 1_700_000_000_000_000_000
PIECE_EXCHANGES = 50_000
DRIVES = range(1, 17)
PRODUCT = b"ATV71HU15M3"
#: Fault rates per exchange.
EXCEPTION, CRC_ERROR, NO_ANSWER, PAUSE, FAST, GLITCH = 0.005, 0.002, 0.003, 0.005, 0.01, 0.01


def adu(*parts: bytes) -> bytes:
    body = b"".join(parts)
    return body + crc_bytes(body)


def words(*values: int) -> bytes:
    return struct.pack(f">{len(values)}H", *values)


class Drives:
    """The values the drives report: drawn anew each time (``random``), or held (``steady``)."""

    STATES = (0x0637, 0x8637, 0x0627)
    #: ``steady``: the chance, per exchange with a drive, that its state and speed change.
    CHANGE = 0.002

    def __init__(self, rng: random.Random, values: str = "random") -> None:
        self._rng, self._steady = rng, values == "steady"
        self._held: dict[int, tuple[int, int, int]] = {}

    def state(self, slave: int) -> int:
        return self._held[slave][0] if self._steady else self._rng.choice(self.STATES)

    def speed(self, slave: int) -> int:
        return self._held[slave][1] if self._steady else self._rng.randrange(0, 1500)

    def high_speed(self, slave: int) -> int:
        return self._held[slave][2] if self._steady else self._rng.randrange(400, 600)

    def next_exchange(self, slave: int) -> None:
        if self._steady and (slave not in self._held or self._rng.random() < self.CHANGE):
            rng = self._rng
            self._held[slave] = (rng.choice(self.STATES), rng.randrange(0, 1500), rng.randrange(400, 600))


def exchange(rng: random.Random, slave: int, drives: Drives) -> tuple[bytes, bytes]:
    """One request and its normal answer, chosen with the frequencies of a PLC's cycle."""
    drives.next_exchange(slave)
    s = bytes([slave])
    kind = rng.random()
    if kind < 0.55:  # ETA and RFRD
        count = rng.choice([1, 2, 4])
        values = [drives.state(slave), *(drives.speed(slave) for _ in range(count - 1))]
        return adu(s, b"\x03", words(3201, count)), adu(s, b"\x03", bytes([2 * count]), words(*values))
    if kind < 0.8:  # CMD and LFRD
        request_words = words(8501, 2) + b"\x04" + words(0x000F, drives.speed(slave))
        return adu(s, b"\x10", request_words), adu(s, b"\x10", words(8501, 2))
    if kind < 0.9:  # HSP
        single = adu(s, b"\x06", words(3104, drives.high_speed(slave)))
        return single, single
    if kind < 0.999:  # the scanner: write NC1-2, read NM1-2
        request = adu(s, b"\x17", words(12741, 2, 12761, 2), b"\x04", words(0x000F, drives.speed(slave)))
        return request, adu(s, b"\x17\x04", words(0x8637, drives.speed(slave)))
    objects = b"\x00\x0dTelemecanique" + b"\x01" + bytes([len(PRODUCT)]) + PRODUCT + b"\x02\x040201"
    return adu(s, b"\x2b\x0e\x01\x00"), adu(s, b"\x2b\x0e\x01\x02\x00\x00\x03", objects)


def transmissions(exchanges: int, rng: random.Random, line: LineSettings, drives: Drives) -> Iterator[Transmission]:
    char_ns, t3_5, t1_5 = round(line.char_time_ns), round(line.t3_5_ns), round(line.t1_5_ns)
    for _ in range(exchanges):
        slave = rng.choice(DRIVES)
        request, answer = exchange(rng, slave, drives)
        yield Transmission(request, t3_5 + rng.randrange(0, 4 * char_ns))
        fault = rng.random()
        if fault < NO_ANSWER:
            yield Transmission(request, 50 * char_ns + rng.randrange(0, 5 * char_ns))  # the retry
            continue
        if fault < NO_ANSWER + EXCEPTION:
            answer = adu(bytes([slave, request[1] | 0x80, rng.choice([2, 4])]))
        elif fault < NO_ANSWER + EXCEPTION + CRC_ERROR:
            damaged = bytearray(answer)
            damaged[rng.randrange(2, len(damaged))] ^= 1 << rng.randrange(8)
            answer = bytes(damaged)
        gaps = {rng.randrange(1, len(answer)): t1_5 + char_ns} if rng.random() < PAUSE else {}
        idle = rng.randrange(char_ns // 2, t1_5) if rng.random() < FAST else t3_5 + rng.randrange(0, 10 * char_ns)
        yield Transmission(answer, idle, gaps)
        if rng.random() < GLITCH:
            yield Transmission(bytes([rng.choice([0x00, 0xFF])]), 0)


def write(
    path: Path, frames: int, seed: int, line: LineSettings, timing: str, *, values: str = "random"
) -> None:
    """``timing``: ``exact``, ``host`` (a USB adapter, 16 ms latency timer) or the name of a
    read loop of benchmarks/read_loops.py."""
    read_loop = None if timing == "exact" else READ_LOOPS["usb-16ms" if timing == "host" else timing]
    rng = random.Random(seed)
    drives = Drives(rng, values)
    note = f"benchmarks.generate_capture seed {seed}" + (f", {values} values" if values != "random" else "")
    quality = TimingQuality.HOST if read_loop else TimingQuality.EXACT
    writer = open_writer(str(path), CaptureInfo(line, quality, (note,)))
    t0_ns = T0_NS
    last_stamp = 0
    try:
        for piece in range(0, frames // 2, PIECE_EXCHANGES):
            exchanges = min(PIECE_EXCHANGES, frames // 2 - piece)
            chunks = list(exact_chunks(transmissions(exchanges, rng, line, drives), line, t0_ns))
            t0_ns = chunks[-1].t_end_ns
            if read_loop is not None:
                # Pieces are delivered one by one: a read of the next never comes before the last of this.
                chunks = [Chunk(max(last_stamp, c.t_end_ns), c.data) for c in read_loop(chunks, line, seed + piece)]
                last_stamp = chunks[-1].t_end_ns
            writer.write_batch(ChunkBatch.from_chunks(chunks))
    finally:
        writer.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("output", type=Path)
    parser.add_argument("--frames", type=int, default=1_000_000, help="about this many frames (requests+answers)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--line", default="115200 8N1")
    parser.add_argument("--timing", choices=["exact", "host", *sorted(READ_LOOPS)], default="exact",
                        help="host: a USB adapter with a 16 ms latency timer; or a read loop (benchmarks.read_loops)")
    parser.add_argument("--values", choices=["random", "steady"], default="random",
                        help="speeds and states drawn anew each time, or held by each drive for a while")
    args = parser.parse_args()
    write(args.output, args.frames, args.seed, LineSettings.parse(args.line), args.timing, values=args.values)


if __name__ == "__main__":
    main()
