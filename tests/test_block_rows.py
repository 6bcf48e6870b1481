"""MCAP's frame records (``FrameRecordEncoder.block_rows``) are the same bytes whether their own
fields were made where frames were paired (``block_fields``, the MCAP export's ``prepare``) or
where they are written (the live Foxglove stream's path), with frames left in columns or not."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from decoders.message import MessageBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from decoders.profiles.apply import ProfileApplier
from sniffer.encoding.frame_fields import block_fields
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.io.registry import open_reader
from sniffer.profiles_io import profile_book

CAPTURES = Path(__file__).resolve().parents[1] / "captures"


def message_batches(path: Path) -> Iterator[MessageBatch]:
    reader = open_reader(str(path))
    decoder = Decoder(reader.info.line, reader.info.timing)
    for chunks in reader.batches():
        yield from decoder.feed(chunks)
    yield from decoder.flush()


@pytest.mark.parametrize("traffic", ["polling", "coils", "mixed", "steady", "atv71-plc-poll-usb.mcap",
                                     "xbt-hmi.mcap", "nord-uss.mcap"])
@pytest.mark.parametrize("in_columns", [True, False])
def test_prepared_fields_give_the_same_records(tmp_path: Path, traffic: str, in_columns: bool) -> None:
    from benchmarks.bench_memory import benchmark_capture

    path = CAPTURES / traffic if traffic.endswith(".mcap") else benchmark_capture(tmp_path, 3000, traffic)
    annotator = Annotator(ProfileApplier(profile_book([], [])))
    prepared, plain = FrameRecordEncoder(exact=False), FrameRecordEncoder(exact=False)
    written = columnar = 0
    for batch in message_batches(path):
        annotated = annotator.annotate_columnar(batch) if in_columns else annotator.annotate_batch(batch)
        columnar += 0 if annotated.columnar is None else len(annotated.columnar)
        with_fields = prepared.block_rows(annotated, 24, fields=block_fields(batch))
        without = plain.block_rows(annotated, 24)
        assert with_fields.data == without.data and with_fields.offsets.tolist() == without.offsets.tolist()
        written += len(with_fields)
    assert written >= 12
    if in_columns and traffic in ("polling", "coils"):
        assert columnar > 1000
    if not in_columns:
        assert columnar == 0
