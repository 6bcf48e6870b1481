"""Framing throughput on a synthetic exact capture; prints a table.

    python -m benchmarks.bench_framing [--frames N]

Stages measured side by side on the same capture in one process:
the vectorised timing pass alone, the whole framer (timing, content pass, CRC,
frame assembly) on the exact capture, on polling that repeats requests ending in 0x00 (which
the content parser reads), and on the same traffic through a USB
adapter model and two pyserial read loops (host timing: every frame found by content;
benchmarks/read_loops.py), the framer plus role
classification (what `analyze` does before output), and reading the native MCAP
capture back.
"""

from __future__ import annotations

import argparse
import random
import struct
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks.read_loops import READ_LOOPS
from benchmarks.wire_synthesis import Transmission, byte_times, exact_chunks, usb_adapter_chunks
from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.framer import Framer
from decoders.line import LineSettings
from decoders.pipeline import Decoder
from sniffer.io.registry import open_reader, open_writer

LINE = LineSettings.parse("115200 8N1")
BATCH_CHUNKS = 8192


def exchange(rng: random.Random, request: bytes, response: bytes,
             gaps: dict[int, int] | None = None) -> list[Transmission]:
    """A request and its response with their CRCs, each after a silence of 2-4 ms and 1.8-3 ms
    (``gaps``: pauses inside the response)."""
    return [Transmission(request + crc_bytes(request), rng.randint(2_000_000, 4_000_000)),
            Transmission(response + crc_bytes(response), rng.randint(1_800_000, 3_000_000), gaps or {})]


def polling_transmissions(frames: int, seed: int = 1) -> list[Transmission]:
    """FC3 request/response pairs to 32 slaves, 1-8 register reads, 1 % gap_1_5."""
    rng = random.Random(seed)
    transmissions = []
    for i in range(frames // 2):
        slave, count = rng.randint(1, 32), rng.randint(1, 8)
        start = rng.randrange(0, 10_000)
        request = bytes([slave, 3]) + start.to_bytes(2, "big") + count.to_bytes(2, "big")
        response = bytes([slave, 3, 2 * count]) + rng.randbytes(2 * count)
        gaps = {5: 1_000_000} if i % 100 == 0 else {}
        transmissions += exchange(rng, request, response, gaps)
    return transmissions


def coil_transmissions(frames: int, seed: int = 1) -> list[Transmission]:
    """Coil traffic, no two frames alike: FC 1/2 reads of 1-64 coils or inputs of 32 slaves with
    random states, FC 5 single writes (echoed) and FC 15 writes of 1-32 coils."""
    rng = random.Random(seed)
    transmissions = []
    for _ in range(frames // 2):
        slave, start, kind = rng.randint(1, 32), rng.randrange(0, 10_000), rng.random()
        if kind < 0.7:
            function, count = rng.choice((1, 2)), rng.randint(1, 64)
            request = bytes([slave, function]) + start.to_bytes(2, "big") + count.to_bytes(2, "big")
            response = bytes([slave, function, (count + 7) // 8]) + rng.randbytes((count + 7) // 8)
        elif kind < 0.85:
            request = response = bytes([slave, 5]) + start.to_bytes(2, "big") + rng.choice((b"\xff\x00", b"\x00\x00"))
        else:
            count = rng.randint(1, 32)
            head = bytes([slave, 15]) + start.to_bytes(2, "big") + count.to_bytes(2, "big")
            request = head + bytes([(count + 7) // 8]) + rng.randbytes((count + 7) // 8)
            response = head
        transmissions += exchange(rng, request, response)
    return transmissions


def wide_transmissions(frames: int, seed: int = 1) -> list[Transmission]:
    """A wide bus: reads of 1-8 coils, inputs or registers (FC 1, 2, 3, 4) of 247 slaves with
    random values, so that a batch of frames touches about 1 000 pairs of slave and function."""
    rng = random.Random(seed)
    transmissions = []
    for _ in range(frames // 2):
        slave, function, count = rng.randint(1, 247), rng.choice((1, 2, 3, 4)), rng.randint(1, 8)
        request = bytes([slave, function]) + rng.randrange(0, 10_000).to_bytes(2, "big") + count.to_bytes(2, "big")
        size = 2 * count if function in (3, 4) else 1
        response = bytes([slave, function, size]) + rng.randbytes(size)
        transmissions += exchange(rng, request, response)
    return transmissions


def meter_transmissions(frames: int, seed: int = 1) -> list[Transmission]:
    """Meters answering floats: FC 3 reads of 2-16 registers at even addresses 0-30 of 32 slaves
    whose registers hold IEEE 754 floats, high word first, each moving a little from one read
    to the next (flows, currents, energies)."""
    rng = random.Random(seed)
    readings = [[rng.uniform(0, 500) for _ in range(16)] for _ in range(32)]
    transmissions = []
    for _ in range(frames // 2):
        slave, first = rng.randint(1, 32), rng.randrange(0, 16)
        floats = rng.randint(1, 16 - first)
        values = readings[slave - 1]
        for place in range(first, first + floats):
            values[place] += rng.gauss(0, 0.5)
        request = bytes([slave, 3]) + (2 * first).to_bytes(2, "big") + (2 * floats).to_bytes(2, "big")
        words = struct.pack(f">{floats}f", *values[first : first + floats])
        transmissions += exchange(rng, request, bytes([slave, 3, len(words)]) + words)
    return transmissions


def register_read_at_0x02xx(slave: int, *, ends_in_zero: bool) -> bytes:
    """An FC 3 request to ``slave`` at 0x02xx (no CRC) whose CRC ends in 0x00, or does not. One
    that does reads as a 7-byte answer (byte count 2) and a glitch too: the content parser decides.
    Slaves 1 to 3 have no such request ending in 0x00 (``StopIteration``)."""
    return next(body for low in range(256) for count in range(1, 126)
                if (crc_bytes(body := bytes([slave, 3, 2, low, 0, count]))[1] == 0) == ends_in_zero)


def zero_ending_transmissions(frames: int, seed: int = 1) -> list[Transmission]:
    """FC 3 polling of 16 slaves, the same request to each every time, 4 of them ending in 0x00
    and reading as a 7-byte answer and a glitch too (start address 0x02xx): segments the fast
    path cannot take whole, so a bus repeats them to the content parser."""
    rng = random.Random(seed)
    requests = {slave: register_read_at_0x02xx(slave, ends_in_zero=slave < 8) for slave in range(4, 20)}
    transmissions = []
    for turn in range(frames // 2):
        request = requests[turn % 16 + 4]
        transmissions += exchange(rng, request, bytes([request[0], 3, 2 * request[5]]) + rng.randbytes(2 * request[5]))
    return transmissions


def batched(chunks: list[Chunk]) -> list[ChunkBatch]:
    return [ChunkBatch.from_chunks(chunks[i : i + BATCH_CHUNKS]) for i in range(0, len(chunks), BATCH_CHUNKS)]


def polling_capture(frames: int, seed: int = 1) -> list[ChunkBatch]:
    """The polling traffic as an exact capture."""
    return batched(list(exact_chunks(polling_transmissions(frames, seed), LINE, 1_700_000_000_000_000_000)))


def host_capture(exact: list[ChunkBatch]) -> list[ChunkBatch]:
    """The same traffic through a USB adapter with a 16 ms latency timer."""
    chunks = [c for b in exact for c in b.chunks()]
    return batched(usb_adapter_chunks(chunks, LINE, latency_ns=16_000_000))


def timing_pass(batches: list[ChunkBatch]) -> int:
    found = 0
    for batch in batches:
        starts, ends = byte_times(batch, LINE.char_time_ns)
        silence = starts[1:] - ends[:-1]
        found += int(np.count_nonzero(silence >= LINE.t3_5_ns))
    return found


def framer(batches: list[ChunkBatch], timing: TimingQuality = TimingQuality.EXACT) -> int:
    framing = Framer(LINE, timing)
    count = sum(len(framing.feed(b)) for b in batches)
    return count + len(framing.flush())


def decoder(batches: list[ChunkBatch]) -> int:
    decode = Decoder(LINE, TimingQuality.EXACT)
    count = sum(len(m) for b in batches for m in decode.feed(b))
    return count + sum(len(m) for m in decode.flush())


def mcap_read(path: Path) -> Callable[[list[ChunkBatch]], int]:
    def read(_: list[ChunkBatch]) -> int:
        reader = open_reader(str(path))
        count = sum(len(b) for b in reader.batches())
        reader.close()
        return count

    return read


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=500_000)
    args = parser.parse_args()
    started = time.perf_counter()
    batches = polling_capture(args.frames)
    total_bytes = sum(len(b.data) for b in batches)
    print(f"capture: {args.frames:,} frames, {total_bytes / 1e6:.1f} MB, {LINE.format()} "
          f"(generated in {time.perf_counter() - started:.1f} s)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        writer = open_writer(str(path), CaptureInfo(LINE, TimingQuality.EXACT))
        for batch in batches:
            writer.write_batch(batch)
        writer.close()
        host = host_capture(batches)
        on_wire = [c for b in batches for c in b.chunks()]
        read_timeout = batched(READ_LOOPS["read-timeout"](on_wire, LINE, 1))
        random_sizes = batched(READ_LOOPS["random-sizes"](on_wire, LINE, 1))
        zero_ending = batched(list(exact_chunks(zero_ending_transmissions(args.frames), LINE,
                                                   1_700_000_000_000_000_000)))
        stages: list[tuple[str, Callable[[list[ChunkBatch]], int], list[ChunkBatch]]] = [
            ("timing pass (numpy)", timing_pass, batches),
            ("framer, exact timing", framer, batches),
            ("framer, exact, 0x00 endings", framer, zero_ending),
            ("framer, host timing (16 ms)", lambda b: framer(b, TimingQuality.HOST), host),
            ("framer, host (read-timeout)", lambda b: framer(b, TimingQuality.HOST), read_timeout),
            ("framer, host (random-sizes)", lambda b: framer(b, TimingQuality.HOST), random_sizes),
            ("framer + matcher, exact", decoder, batches),
            ("MCAP capture read", mcap_read(path), batches),
        ]
        print(f"{'stage':<30} {'seconds':>8} {'frames/s':>12} {'MB/s':>8}")
        for name, stage, data in stages:
            start = time.perf_counter()
            found = stage(data)
            assert name.startswith(("timing", "MCAP")) or found == args.frames, (name, found)
            seconds = time.perf_counter() - start
            print(f"{name:<30} {seconds:>8.3f} {args.frames / seconds:>12,.0f} {total_bytes / seconds / 1e6:>8.1f}")


if __name__ == "__main__":
    main()
