"""The columnar MCAP writer, read back by the ``mcap`` package's readers (indexed and streamed)."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, MessageIndex
from mcap.stream_reader import StreamReader

from sniffer.encoding.rows import join_rows
from sniffer.exports.mcap_writer import HEADER_SIZE, ColumnarMcapWriter, MessageBlock


def _block(payloads: list[bytes], channels: list[int], times: list[int]) -> MessageBlock:
    return MessageBlock(
        join_rows([payloads], len(payloads), HEADER_SIZE), np.array(channels, np.uint16), np.array(times, np.int64)
    )


def _write(chunk_size: int) -> tuple[bytes, list[tuple[int, int, bytes]]]:
    """Three channels, 300 messages over three blocks, a channel added between blocks."""
    out = io.BytesIO()
    writer = ColumnarMcapWriter(out, profile="test", library="tests", chunk_size=chunk_size)
    writer.add_metadata("first", {"a": "1"})
    schema = writer.add_schema("s", "jsonschema", b"{}")
    one, two = writer.add_channel("/one", "json", schema, {}), writer.add_channel("/two", "raw", 0, {"k": "v"})
    expected: list[tuple[int, int, bytes]] = []
    for block in range(3):
        if block == 2:
            three = writer.add_channel("/three", "json", schema, {})
        payloads, channels, times = [], [], []
        for number in range(100):
            channel = (one, two, three)[number % 3] if block == 2 else (one, two)[number % 2]
            # Times go back now and then (a timeout is written at its request's end).
            t = 1_000_000 * (block * 100 + number + 1) - (500_000 if number % 7 == 0 else 0)
            payload = b'{"n":%d}' % (block * 100 + number) * (1 + number % 5)
            payloads.append(payload), channels.append(channel), times.append(t)
            expected.append((channel, t, payload))
        writer.write(_block(payloads, channels, times))
    writer.add_metadata("last", {"b": "2"})
    writer.close()
    return out.getvalue(), expected


@pytest.mark.parametrize("chunk_size", [1, 700, 1 << 20])
def test_indexed_reader_finds_every_message(chunk_size: int) -> None:
    data, expected = _write(chunk_size)
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    statistics = summary.statistics
    assert statistics.message_count == len(expected) and statistics.channel_count == 3
    assert statistics.message_start_time == min(t for _, t, _ in expected)
    assert statistics.message_end_time == max(t for _, t, _ in expected)
    assert statistics.channel_message_counts == {1: 134, 2: 133, 3: 33}
    assert statistics.metadata_count == 2 and statistics.chunk_count == len(summary.chunk_indexes)
    assert (len(summary.chunk_indexes) == 1) == (chunk_size == 1 << 20)
    assert {c.topic: c.metadata for c in summary.channels.values()}["/two"] == {"k": "v"}
    read = [(channel.id, message.log_time, message.data) for _, channel, message in reader.iter_messages()]
    assert read == sorted(expected, key=lambda m: m[1])  # in time order, across chunks
    assert {m.name: m.metadata for m in reader.iter_metadata()} == {"first": {"a": "1"}, "last": {"b": "2"}}


@pytest.mark.parametrize("chunk_size", [1, 700, 1 << 20])
def test_stream_holds_messages_in_order_and_message_indexes_point_at_them(chunk_size: int) -> None:
    data, expected = _write(chunk_size)
    written, channels_seen = [], set()
    last_chunk: Chunk | None = None
    for record in StreamReader(io.BytesIO(data), skip_magic=False, emit_chunks=True).records:
        if isinstance(record, Channel):
            channels_seen.add(record.id)
        elif isinstance(record, Chunk):
            last_chunk = record
            for channel, log_time, payload in _chunk_messages(_unzstd(record.data)):
                assert channel in channels_seen  # a channel comes before its messages
                written.append((channel, log_time, payload))
        elif isinstance(record, MessageIndex):
            assert last_chunk is not None
            records = _unzstd(last_chunk.data)
            times = [t for t, _ in record.records]
            assert times == sorted(times)
            for t, offset in record.records:
                opcode, _length, channel, _sequence, log_time = struct.unpack_from("<BQHIQ", records, offset)
                assert (opcode, channel, log_time) == (0x05, record.channel_id, t)
    assert written == expected  # the order given


def _chunk_messages(records: bytes) -> list[tuple[int, int, bytes]]:
    """The Message records of a chunk, read by the spec's layout."""
    found, offset = [], 0
    while offset < len(records):
        opcode, length = struct.unpack_from("<BQ", records, offset)
        assert opcode == 0x05
        channel, _sequence, log_time, publish_time = struct.unpack_from("<HIQQ", records, offset + 9)
        assert publish_time == log_time
        found.append((channel, log_time, records[offset + 9 + 22 : offset + 9 + length]))
        offset += 9 + length
    return found


def _unzstd(data: bytes) -> bytes:
    import zstandard

    return zstandard.ZstdDecompressor().decompressobj().decompress(data)


def test_rows_must_reserve_the_header() -> None:
    with pytest.raises(ValueError, match="reserve"):
        MessageBlock(join_rows([[b"x"]], 1), np.array([1], np.uint16), np.array([0], np.int64))


def test_a_full_disk_is_raised_by_the_writer(tmp_path: Path) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    with open("/dev/full", "wb", buffering=0) as full:
        writer = ColumnarMcapWriter(full, profile="test", library="tests", chunk_size=1 << 20)
        channel = writer.add_channel("/one", "json", 0, {})
        writer.write(_block([b"{}" * 1000] * 100, [channel] * 100, list(range(100))))
        with pytest.raises(OSError, match="No space left"):
            writer.flush()
        with pytest.raises(OSError):
            writer.close()
