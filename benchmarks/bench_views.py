"""The terminal views' own cost, side by side in one run; prints a table.

    python -m benchmarks.bench_views [--frames 200000] [--pairs 1235] [--keep DIR]

1. ``stats`` of a capture with thousands of slave/function pairs (every slave 1-247 polled with
   FC 1, 3, 4, 6 and 16): counting the statistics, then laying out the table, against the same
   rows as one rich ``Table`` (what ``stats`` drew before).
2. The ``analyze`` table from annotated batches (the decoding done beforehand, once): plain lines
   for a pipe, the 120-column terminal layout, and the JSONL records of the same batches, per
   benchmark traffic (benchmarks/bench_memory.py).

End to end against tshark's one-line summary: ``python -m benchmarks.bench_tshark``.
"""

from __future__ import annotations

import argparse
import io
import random
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from benchmarks.bench_memory import add_capture_options, benchmark_capture
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.decoded_batch import AnnotatedBatch
from decoders.line import LineSettings
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.stats import Statistics
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.io.registry import open_reader, open_writer
from sniffer.views.clock import Clock
from sniffer.views.stats_view import FUNCTION_COLUMNS, StatsView
from sniffer.views.table import TableView

LINE = LineSettings.parse("115200 8N1")


def many_pairs_capture(path: Path, rounds: int = 3) -> Path:
    """Every slave polled with five functions, ``rounds`` times: about 1 235 slave/function pairs."""
    rng, transmissions = random.Random(1), list[Transmission]()
    for _ in range(rounds):
        for slave in range(1, 248):
            for function in (1, 3, 4, 6, 16):
                address = rng.randrange(1000)
                if function == 6:
                    request = bytes([slave, 6]) + address.to_bytes(2, "big") + b"\x00\x07"
                    answer = request
                elif function == 16:
                    request = bytes([slave, 16]) + address.to_bytes(2, "big") + b"\x00\x01\x02\x00\x07"
                    answer = request[:6]
                else:
                    request = bytes([slave, function]) + address.to_bytes(2, "big") + b"\x00\x02"
                    answer = bytes([slave, function, 4 if function in (3, 4) else 1]) + bytes(
                        4 if function in (3, 4) else 1)
                transmissions += [Transmission(request + crc_bytes(request), 3_000_000),
                                  Transmission(answer + crc_bytes(answer), 2_000_000)]
    writer = open_writer(str(path), CaptureInfo(LINE, TimingQuality.EXACT))
    writer.write_batch(ChunkBatch.from_chunks(list(exact_chunks(transmissions, LINE, 1_700_000_000 * 10**9))))
    writer.close()
    return path


def seconds(work: object) -> float:
    start = time.perf_counter()
    work()  # type: ignore[operator]
    return time.perf_counter() - start


def decoded(capture: Path) -> tuple[list[AnnotatedBatch], Statistics]:
    reader = open_reader(str(capture))
    decoder, annotator, statistics = Decoder(LINE, TimingQuality.EXACT), Annotator(), Statistics()
    batches = []
    for chunks in reader.batches():
        for batch in decoder.feed(chunks):
            statistics.add_batch(batch)
            batches.append(annotator.annotate_batch(batch))
    for batch in decoder.flush():
        statistics.add_batch(batch)
        batches.append(annotator.annotate_batch(batch))
    reader.close()
    return batches, statistics


def rich_table(statistics: Statistics) -> None:
    """The same rows as one rich Table (how ``stats`` drew them before)."""
    view = StatsView(io.StringIO(), width=None)
    view.start("x", CaptureInfo(LINE, TimingQuality.EXACT), LINE)
    table = Table()
    for column in FUNCTION_COLUMNS:
        table.add_column(column.header)
    for (slave, function), stats in sorted(statistics.per_function.items()):
        row = view._cells(slave, function, stats)
        table.add_row(*(row[c.key] for c in FUNCTION_COLUMNS))
    Console(file=io.StringIO(), width=200).print(table)


def stats_rows(folder: Path) -> None:
    capture = many_pairs_capture(folder / "pairs.mcap")
    counting = time.perf_counter()
    _, statistics = decoded(capture)
    counted = time.perf_counter() - counting
    pairs = len(statistics.per_function)

    def laid_out(width: int | None) -> None:
        view = StatsView(io.StringIO(), width=width)
        view.start("x", CaptureInfo(LINE, TimingQuality.EXACT), LINE)
        view.finish(statistics)

    print(f"stats of {statistics.frames:,} frames, {pairs:,} slave/function pairs")
    print(f"  decode and count (all stages, one process)   {counted:8.3f} s")
    print(f"  table, plain lines (a pipe)                  {seconds(lambda: laid_out(None)):8.3f} s")
    print(f"  table, terminal layout, 120 columns          {seconds(lambda: laid_out(120)):8.3f} s")
    print(f"  the same rows as one rich Table              {seconds(lambda: rich_table(statistics)):8.3f} s")


def frame_rows(folder: Path, frames: int, traffic: str) -> None:
    batches, _ = decoded(benchmark_capture(folder, frames, traffic))
    count = sum(len(b) for b in batches)

    def table(width: int | None) -> None:
        view = TableView(io.StringIO(), width=width, clock=Clock("utc"))
        for batch in batches:
            view.messages(batch)

    def jsonl() -> None:
        encoder = FrameRecordEncoder()
        for batch in batches:
            encoder.rows(batch, end=b"\n")

    results = [(name, seconds(work)) for name, work in (
        ("plain lines", lambda: table(None)), ("terminal, 120 columns", lambda: table(120)), ("JSONL records", jsonl))]
    print(f"{traffic:>8} ({count:,} frames) " + "   ".join(
        f"{name} {count / took:>10,.0f} frames/s" for name, took in results))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200_000)
    add_capture_options(parser)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        stats_rows(Path(tmp))
        print("analyze table from annotated batches (rendering only, one process):")
        for traffic in ("steady", "mixed", "polling"):
            frame_rows(folder, args.frames, traffic)


if __name__ == "__main__":
    main()
