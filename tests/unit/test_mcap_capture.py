"""The native MCAP capture, checked with the standard mcap reader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from benchmarks.hostile_inputs import crafted_mcap, first_chunk_offset
from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io import mcap_blocks
from sniffer.io.mcap_blocks import decode_block, encode_block, longest_chunk
from sniffer.io.mcap_native import McapCaptureReader, McapCaptureWriter
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


def test_a_block_whose_chunk_times_go_back_is_refused() -> None:
    batch = sample_batch(5)
    times = batch.t_end_ns.copy()
    times[3] = times[1]  # earlier than the chunk before it
    with pytest.raises(ValueError, match="chunk times decrease inside a block"):
        decode_block(encode_block(ChunkBatch(batch.data, batch.ends, times)))
    times[3] = times[2]  # the same time as the chunk before it: allowed
    assert decode_block(encode_block(ChunkBatch(batch.data, batch.ends, times))).t_end_ns.tolist() == times.tolist()


def test_the_longest_chunk_of_a_block_is_read_from_its_lengths() -> None:
    batch = sample_batch(300)
    assert longest_chunk(encode_block(batch)) == int(np.diff(batch.ends, prepend=0).max())
    assert longest_chunk(encode_block(ChunkBatch.empty())) == 0
    for lengths in ([1, 5, 80], [80, 5, 1], [7]):
        chunks = [Chunk(1_700_000_000_000_000_000 + k, bytes(n)) for k, n in enumerate(lengths)]
        assert longest_chunk(encode_block(ChunkBatch.from_chunks(chunks))) == max(lengths)


def test_standard_reader_sees_blocks_and_metadata(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    batch = sample_batch(10_000)
    write(path, batch)
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        [channel] = summary.channels.values()
        assert channel.topic == mcap_blocks.TOPIC
        assert summary.statistics is not None
        assert summary.statistics.message_count == 3  # 10 000 chunks in blocks of 4096
        assert summary.chunk_indexes and summary.chunk_indexes[0].compression == "zstd"
        [metadata] = [m for m in reader.iter_metadata() if m.name == mcap_blocks.METADATA_NAME]
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


def marked_batch(count: int) -> ChunkBatch:
    """:func:`sample_batch` with a UART error on about one byte in fifty."""
    batch = sample_batch(count)
    kinds = np.random.default_rng(6).choice(np.array([0, 1, 2, 3], np.uint8), len(batch.data),
                                            p=[0.98, 0.01, 0.005, 0.005])
    return ChunkBatch(batch.data, batch.ends, batch.t_end_ns, kinds)


def test_uart_errors_round_trip_and_a_plain_reader_still_reads_every_byte(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    batch = marked_batch(10_000)
    write(path, batch)
    reader = McapCaptureReader(str(path))
    chunks = [c for b in reader.batches() for c in b.chunks()]
    reader.close()
    assert chunks == list(batch.chunks())
    assert sum(len(c.uart_errors) for c in chunks) == int(np.count_nonzero(batch.uart_errors))
    with path.open("rb") as f:  # a reader that knows only the chunk topic, as rtusniff's before
        blocks = [decode_block(m.data) for _, channel, m in make_reader(f).iter_messages()
                  if channel.topic == mcap_blocks.TOPIC]
    assert b"".join(b.data for b in blocks) == batch.data


def test_a_capture_without_uart_errors_has_no_errors_channel(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    write(path, sample_batch(100))
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and [c.topic for c in summary.channels.values()] == [mcap_blocks.TOPIC]


@pytest.mark.parametrize(("payload", "size"), [(b"", 4), (b"\x01\x00\x00\x00\x05\x00\x00\x00\x01", 4),
                                               (b"\x01\x00\x00\x00\x00\x00\x00\x00\x09", 4),
                                               (b"\x01\x00\x00\x00\x00\x00\x00\x00", 4)])
def test_inconsistent_uart_errors_are_refused(payload: bytes, size: int) -> None:
    with pytest.raises(ValueError):
        mcap_blocks.decode_errors(payload, size)


def test_channels_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "c.mcap"
    plain = marked_batch(6000)
    channels = np.random.default_rng(7).integers(0, 3, len(plain)).astype(np.uint8)
    batch = ChunkBatch(plain.data, plain.ends, plain.t_end_ns, plain.uart_errors, channels)
    info = CaptureInfo(INFO.line, INFO.timing, INFO.notes, ("RX", "TX"))
    write(path, batch, info)
    reader = McapCaptureReader(str(path))
    assert reader.info == info
    chunks = [c for b in reader.batches() for c in b.chunks()]
    reader.close()
    assert chunks == list(batch.chunks())
    assert [c.channel for c in chunks] == channels.tolist()


def test_a_channel_beyond_the_names_is_refused() -> None:
    with pytest.raises(ValueError):
        mcap_blocks.decode_channels(mcap_blocks.encode_channels(np.array([1, 3], np.uint8)), 2, 2)
    with pytest.raises(ValueError):
        mcap_blocks.decode_channels(mcap_blocks.encode_channels(np.array([1], np.uint8)), 2, 2)


FIELDS = {"format_version": "1", "timing": "exact", "line": "19200 8E1", "notes": "[]"}
T0 = 1_700_000_000_000_000_000


def block_at(*times: int) -> ChunkBatch:
    return ChunkBatch.from_chunks([Chunk(t, b"\x01\x03") for t in times])


@pytest.mark.parametrize(("fields", "blocks", "late", "said"), [
    ({**FIELDS, "notes": '{"a": 1}'}, [block_at(T0)], None, "'rtusniff.capture' notes: not a JSON list of strings"),
    ({**FIELDS, "notes": "[1, 2]"}, [block_at(T0)], None, "'rtusniff.capture' notes: not a JSON list of strings"),
    (FIELDS, [block_at(T0)], "nope", "'rtusniff.notes': not a JSON list of strings"),
    (FIELDS, [block_at(T0, T0 + 10), block_at(T0 + 5)], None, "times must not decrease"),
    (FIELDS, [block_at(-5, 0)], None, "a time before 1970"),
])
def test_crafted_metadata_and_times_are_one_error(tmp_path: Path, fields: dict[str, str], blocks: list[ChunkBatch],
                                                  late: str | None, said: str) -> None:
    path = crafted_mcap(tmp_path / "crafted.mcap", fields, blocks, late)
    with pytest.raises(CaptureFormatError) as caught:
        reader = McapCaptureReader(str(path))
        try:
            list(reader.batches())
        finally:
            reader.close()
    assert caught.value.kind is ErrorKind.BAD_MCAP and said in str(caught.value) and str(path) in str(caught.value)


def test_a_flipped_bit_is_an_error_or_changes_nothing(tmp_path: Path) -> None:
    """Chunk CRCs are checked: a bit flipped anywhere in the file reads as one error, or (in
    what the capture does not use: an index, padding) as the same chunks -- never as different
    frames read as good."""
    from tests.conftest import SAMPLE_MCAP

    original = SAMPLE_MCAP.read_bytes()

    def chunks_of(path: Path) -> list[Chunk] | None:
        try:
            reader = McapCaptureReader(str(path))
            try:
                return [chunk for batch in reader.batches() for chunk in batch.chunks()]
            finally:
                reader.close()
        except CaptureFormatError:
            return None

    good = chunks_of(SAMPLE_MCAP)
    damaged = tmp_path / "flipped.mcap"
    silent = []
    for offset in range(8, len(original) - 8, 3):
        data = bytearray(original)
        data[offset] ^= 1 << (offset % 8)
        damaged.write_bytes(bytes(data))
        read = chunks_of(damaged)
        if read is not None and read != good:
            silent.append(offset)
    assert silent == []


def test_a_chunk_claiming_gigabytes_is_refused_before_it_is_decompressed(tmp_path: Path) -> None:
    """A few kilobytes of zstd may claim 7 GB: the claim is checked first, in one error that says
    how to raise the limit; no memory is asked for."""
    path = tmp_path / "bomb.mcap"
    write(path, sample_batch(50))
    data = bytearray(path.read_bytes())
    size_at = first_chunk_offset(data) + 9 + 16  # opcode, length, start and end times
    data[size_at : size_at + 8] = (7 * 2**30).to_bytes(8, "little")
    path.write_bytes(bytes(data))
    with pytest.raises(CaptureFormatError) as error:
        reader = McapCaptureReader(str(path))
        list(reader.batches())
    assert error.value.kind is ErrorKind.BAD_MCAP
    assert "claims 7,516,192,768 bytes uncompressed" in str(error.value)
    assert mcap_blocks.LIMIT_VARIABLE in str(error.value)


def test_the_limit_can_be_raised(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RTUSNIFF_MAX_READ_MB", "4")  # a single read of 2 MiB is over the read limit too
    monkeypatch.setenv(mcap_blocks.LIMIT_VARIABLE, "1")
    path = tmp_path / "big.mcap"
    t0 = 1_700_000_000_000_000_000
    write(path, ChunkBatch.from_chunks([Chunk(t0, bytes(2**21))]))  # one read of 2 MiB: one block
    with pytest.raises(CaptureFormatError, match="1 MiB"):
        list(McapCaptureReader(str(path)).batches())
    monkeypatch.setenv(mcap_blocks.LIMIT_VARIABLE, "4")
    assert sum(len(b.data) for b in McapCaptureReader(str(path)).batches()) == 2**21


def test_blocks_are_bounded_in_bytes_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Large reads make more blocks (each at most BLOCK_BYTES, or one larger read), read back whole."""
    monkeypatch.setenv("RTUSNIFF_MAX_READ_MB", "32")
    t0 = 1_700_000_000_000_000_000
    rng = np.random.default_rng(7)
    sizes = [6 << 20, 6 << 20, 6 << 20, 20 << 20, 9]
    chunks = [Chunk(t0 + i * 1_000_000, rng.bytes(size)) for i, size in enumerate(sizes)]
    batch = ChunkBatch.from_chunks(chunks)
    blocks = list(mcap_blocks.block_batches(batch))
    assert [len(block) for block in blocks] == [2, 1, 1, 1]
    path = tmp_path / "large.mcap"
    write(path, batch)
    read = list(McapCaptureReader(str(path)).batches())
    assert b"".join(b.data for b in read) == batch.data


def test_small_blocks_are_read_as_few_batches(tmp_path: Path) -> None:
    """A recording flushes a block a second: read back, small blocks join into batches of up to
    BATCH_CHUNKS chunks (the decoder's cost is per batch), every byte and time as written."""
    batch = sample_batch(3000)
    path = tmp_path / "small-blocks.mcap"
    writer = McapCaptureWriter(str(path), INFO)
    for start in range(0, len(batch), 3):
        writer.write_batch(batch.slice(start, start + 3))
    writer.close()
    read = list(McapCaptureReader(str(path)).batches())
    assert len(read) == 1
    assert read[0].data == batch.data
    assert read[0].t_end_ns.tolist() == batch.t_end_ns.tolist() and read[0].ends.tolist() == batch.ends.tolist()


def test_a_read_over_the_limit_is_one_error_saying_how_to_raise_it(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "one-big-read.mcap"
    write(path, ChunkBatch.from_chunks([Chunk(1_700_000_000_000_000_000, bytes(3 * 2**20))]))
    with pytest.raises(CaptureFormatError, match="RTUSNIFF_MAX_READ_MB") as error:
        list(McapCaptureReader(str(path)).batches())
    assert "one read of 3,145,728 bytes" in str(error.value)
    monkeypatch.setenv("RTUSNIFF_MAX_READ_MB", "3")
    assert sum(len(b.data) for b in McapCaptureReader(str(path)).batches()) == 3 * 2**20
