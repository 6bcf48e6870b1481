"""What bounds `analyze --format jsonl` and the exports: stage by stage, per kind of traffic; prints a table.

    python -m benchmarks.bench_stages [--frames 200000] [--keep DIR]

Four captures of the same size (benchmarks/bench_memory.py): ``steady`` drives that hold their
state and speed (what a running plant sends: the same frames again and again), ``mixed`` ATV
traffic whose values are drawn anew for every answer, ``polling`` of random registers with
random values (no two frames alike), and ``coils`` (reads and writes of up to 64 random coils:
no two alike, and a param per coil). Stages, one process, one core:

1. read the MCAP capture, frame, pair, count statistics (all in columns);
2. + annotate: decode each distinct frame once (a Python object per distinct frame);
3. + JSONL: the frame records, written from columns and per-decoding parts;
4. annotate + MCAP export (instead of JSONL): every channel built in columns and written in blocks;
5. annotate + Rerun export (instead of JSONL): every entity buffered and sent in columns.

The last lines time MCAP writers alone on the same messages (160 bytes of hex text, zstd
chunks), side by side: the export's columnar writer (blocks of 4096), the ``mcap`` package's
Python writer and, where it is installed, foxglove-sdk's Rust writer (one call per message).
The export writes three to four messages per frame.

The ``distinct`` column is the share of frames the annotator had to decode: the rest were
repeats answered from its cache. Per-frame Python work on the distinct ones is what bounds
the throughput.
"""

from __future__ import annotations

import argparse
import gc
import random
import tempfile
import time
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer

from benchmarks.bench_memory import benchmark_capture
from decoders.message import MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier
from decoders.stats import Statistics
from sniffer.allocator import keep_freed_memory
from sniffer.cli import GC_YOUNG_THRESHOLD
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.encoding.rows import join_rows
from sniffer.exports.mcap_export import CHUNK_SIZE, McapExporter
from sniffer.exports.mcap_writer import HEADER_SIZE, ColumnarMcapWriter, MessageBlock
from sniffer.exports.rerun_export import RerunExporter
from sniffer.io.registry import open_reader
from sniffer.profiles_io import profile_book

STAGES = ("read, frame, pair, statistics", "+ annotate", "+ JSONL records", "+ annotate, MCAP export",
          "+ annotate, Rerun export")
TRAFFIC = ("steady", "mixed", "polling", "coils")


class _CountingAnnotator(Annotator):
    """Counts the frames it decodes (the distinct ones): those its memo of decodings misses."""

    def __init__(self, profiles: ProfileApplier) -> None:
        super().__init__(profiles)
        self.decoded = 0
        older = self._decodings.older

        def counting(key):  # type: ignore[no-untyped-def]
            found = older(key)
            self.decoded += found is None
            return found

        self._decodings.older = counting  # type: ignore[method-assign]


def run(capture: Path, stage: int, output: Path) -> tuple[float, int, int]:
    """Seconds for ``stage`` (1-based, see STAGES), frames, and frames decoded."""
    reader = open_reader(str(capture))
    line = reader.info.line
    assert line is not None
    decoder = Decoder(line, reader.info.timing)
    annotator = _CountingAnnotator(ProfileApplier(profile_book([], [])))
    encoder, statistics, frames = FrameRecordEncoder(), Statistics(), 0
    mcap = McapExporter(str(output / f"{capture.stem}.mcap"), reader.info, line, {}) if stage == 4 else None
    rerun = RerunExporter(str(output / f"{capture.stem}.rrd")) if stage == 5 else None
    start = time.perf_counter()

    def deliver(batches: list[MessageBatch]) -> None:
        nonlocal frames
        for batch in batches:
            statistics.add_batch(batch)
            frames += len(batch)
            if stage >= 2:
                annotated = annotator.annotate_batch(batch)
                if stage == 3:
                    encoder.rows(annotated, end=b"\n")  # what the JSONL view writes (as bytes)
                for exporter in filter(None, (mcap, rerun)):
                    exporter.messages(annotated)

    for chunks in reader.batches():
        if mcap is not None:
            mcap.raw(chunks)
        deliver(decoder.feed(chunks))
    deliver(decoder.flush())
    for exporter in filter(None, (mcap, rerun)):
        exporter.close()
    return time.perf_counter() - start, frames, annotator.decoded


def _payloads() -> list[bytes]:
    return [random.randbytes(80).hex().encode() for _ in range(1024)]


def columnar_writer_alone(output: Path, messages: int = 1_000_000, block: int = 4096) -> float:
    """The export's writer: seconds per message, blocks built from the payloads' list."""
    payloads = _payloads() * (block // 1024)
    channels, times = np.ones(block, np.uint16), np.arange(block, dtype=np.int64)
    with (output / "columnar.mcap").open("wb") as file:
        writer = ColumnarMcapWriter(file, profile="bench", library="bench", chunk_size=CHUNK_SIZE)
        channel = writer.add_channel("/bench", "raw", 0, {})
        channels[:] = channel
        start = time.perf_counter()
        for first in range(0, messages, block):
            writer.write(MessageBlock(join_rows([payloads], block, HEADER_SIZE), channels, times + first))
        writer.close()
    return (time.perf_counter() - start) / messages


def mcap_python_writer_alone(output: Path, messages: int = 200_000) -> float:
    """The ``mcap`` package's writer, one call per message."""
    payloads = _payloads()
    with (output / "python.mcap").open("wb") as file:
        writer = Writer(file, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        writer.start()
        channel = writer.register_channel("/bench", "raw", 0)
        start = time.perf_counter()
        for index in range(messages):
            writer.add_message(channel, index, payloads[index & 1023], index)
        writer.finish()
    return (time.perf_counter() - start) / messages


def foxglove_writer_alone(output: Path, messages: int = 1_000_000) -> float | None:
    """foxglove-sdk's Rust writer, one call per message; ``None`` where it is not installed
    (it is no dependency: the export's writer replaced it)."""
    try:
        import foxglove
        from foxglove import Channel, Context, Schema
        from foxglove.mcap import MCAPCompression, MCAPWriteOptions
    except ImportError:
        return None
    context = Context()
    options = MCAPWriteOptions(compression=MCAPCompression.Zstd, chunk_size=CHUNK_SIZE, compression_threads=0)
    writer = foxglove.open_mcap(str(output / "foxglove.mcap"), allow_overwrite=True, context=context,
                                writer_options=options)
    channel = Channel("/bench", schema=Schema(name="bench", encoding="", data=b""), message_encoding="raw",
                      context=context)
    payloads, log = _payloads(), channel.base.log
    start = time.perf_counter()
    for index in range(messages):
        log(payloads[index & 1023], index, None)
    writer.close()
    return (time.perf_counter() - start) / messages


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated captures in this folder")
    args = parser.parse_args()
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    keep_freed_memory()  # as the command line does
    with tempfile.TemporaryDirectory() as tmp:
        captures = {traffic: benchmark_capture(args.keep or Path(tmp), args.frames, traffic) for traffic in TRAFFIC}
        print(f"frames/s, {args.frames:,} frames per capture")
        print(f"{'stage':<32}" + "".join(f"{traffic:>12}" for traffic in TRAFFIC))
        distinct = {}
        for stage in range(1, len(STAGES) + 1):
            row = []
            for traffic in TRAFFIC:
                seconds, frames, decoded = run(captures[traffic], stage, Path(tmp))
                row.append(f"{frames / seconds:>12,.0f}")
                if stage == len(STAGES):
                    distinct[traffic] = decoded / frames
            print(f"{STAGES[stage - 1]:<32}" + "".join(row))
        print(f"{'distinct (decoded) frames':<32}" + "".join(f"{distinct[t]:>12.1%}" for t in TRAFFIC))
        for name, writer in (("columnar (the export's)", columnar_writer_alone),
                             ("mcap package, per message", mcap_python_writer_alone),
                             ("foxglove-sdk, per message", foxglove_writer_alone)):
            per_message = writer(Path(tmp))
            if per_message is not None:
                print(f"MCAP writer alone, {name}: {1 / per_message:,.0f} messages/s "
                      f"({per_message * 1e6:.2f} µs a message)")


if __name__ == "__main__":
    main()
