"""The native MCAP capture, checked with the standard mcap reader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io import mcap_native
from sniffer.io.mcap_native import McapCaptureReader, McapCaptureWriter, decode_block, encode_block
from tests.conftest import write_foreign_mcap

INFO = CaptureInfo(LineSettings.parse("19200 8E1"), TimingQuality.EXACT, ("site: pump house", "tap on port 1"))


def sample_batch(count: int) -> ChunkBatch:
    rng = np.random.default_rng(5)
    t0 = 1_700_000_000_000_000_000
    chunks = [Chunk(t0 + i * 3_000_000, rng.bytes(int(rng.integers(1, 60)))) for i in range(count)]
    return ChunkBatch.from_chunks(chunks)


def write(path: Path, batch: ChunkBatch, info: CaptureInfo = INFO) -> None:
    writer = McapCaptureWriter(str(path), info)
    writer.write_batch(batch)
    writer.close()


def test_block_encoding_round_trip() -> None:
    batch = sample_batch(100)
    back = decode_block(encode_block(batch))
    assert back.data == batch.data
    assert back.ends.tolist() == batch.ends.tolist()
    assert back.t_end_ns.tolist() == batch.t_end_ns.tolist()


@pytest.mark.parametrize(
    "payload", [b"", b"\x05\x00\x00\x00", encode_block(sample_batch(3))[:-1], encode_block(sample_batch(3)) + b"x"]
)
def test_inconsistent_blocks_are_refused(payload: bytes) -> None:
    with pytest.raises(ValueError):
        decode_block(payload)


def test_standard_reader_sees_blocks_and_metadata(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    batch = sample_batch(10_000)
    write(path, batch)
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        [channel] = summary.channels.values()
        assert channel.topic == mcap_native.TOPIC
        assert summary.statistics is not None
        assert summary.statistics.message_count == 3  # 10 000 chunks in blocks of 4096
        assert summary.chunk_indexes and summary.chunk_indexes[0].compression == "zstd"
        [metadata] = [m for m in reader.iter_metadata() if m.name == mcap_native.METADATA_NAME]
        assert metadata.metadata["line"] == "19200 8E1"
        assert metadata.metadata["timing"] == "exact"
        assert json.loads(metadata.metadata["notes"]) == list(INFO.notes)
        payloads = [m.data for _, _, m in reader.iter_messages()]
    assert b"".join(decode_block(p).data for p in payloads) == batch.data


def test_reader_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    batch = sample_batch(5000)
    write(path, batch)
    reader = McapCaptureReader(str(path))
    assert reader.info == INFO
    chunks = [c for b in reader.batches() for c in b.chunks()]
    reader.close()
    assert chunks == list(batch.chunks())


def test_mcap_from_another_tool(tmp_path: Path) -> None:
    path = tmp_path / "other.mcap"
    write_foreign_mcap(path)
    with pytest.raises(CaptureFormatError) as caught:
        McapCaptureReader(str(path))
    assert caught.value.kind is ErrorKind.BAD_MCAP
    assert "not an rtusniff capture" in str(caught.value)


def test_not_an_mcap_at_all(tmp_path: Path) -> None:
    path = tmp_path / "text.mcap"
    path.write_text("# rtu-capture v1\n")
    with pytest.raises(CaptureFormatError) as caught:
        McapCaptureReader(str(path))
    assert caught.value.kind is ErrorKind.BAD_MCAP
    assert str(caught.value).startswith(f"{path}:byte ")
