"""An MCAP writer that takes messages a block at a time, as columns.

The ``mcap`` package's writer and foxglove-sdk's both take one message per call: at three or
four messages per frame, those calls alone cost more than everything else an export does per
frame. Here a block of messages is one :class:`~sniffer.encoding.rows.Rows` (payloads laid end to
end, each after a reserved slot for its record header) with a channel id and a log time per
message; numpy fills in all the record headers at once, and the rows are already the chunk's
bytes. Compression, CRCs and file writes run on one worker thread (zstd and zlib release the
GIL): the next block is built while the last chunk is compressed.

The file is what the spec (mcap.dev/spec) asks of an indexed file: header, schemas and
channels in the data section before their first message, zstd chunks each followed by their
message indexes, metadata, then a summary section (schemas, channels, statistics, chunk and
metadata indexes, summary offsets) and the footer with the summary's CRC. The small records
are serialised by the ``mcap`` package's own record classes.
"""

from __future__ import annotations

import struct
import zlib
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np
import numpy.typing as npt
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from sniffer.encoding.rows import Rows

MAGIC = b"\x89MCAP0\r\n"
#: opcode, record length, channel id, sequence, log time, publish time: before every payload.
MESSAGE_HEADER = np.dtype(
    [
        ("opcode", "u1"),
        ("length", "<u8"),
        ("channel", "<u2"),
        ("sequence", "<u4"),
        ("log_time", "<u8"),
        ("publish_time", "<u8"),
    ]
)
HEADER_SIZE = MESSAGE_HEADER.itemsize
_HEADER_AFTER_LENGTH = HEADER_SIZE - 9
_HEADER_PLACES = np.arange(HEADER_SIZE)
_MESSAGE_INDEX = struct.Struct("<BQHI")
#: Chunks compressed or waiting on the worker: more, and the builder waits (memory stays bounded).
MAX_QUEUED_CHUNKS = 2


@dataclass(frozen=True)
class MessageBlock:
    """Messages to write: payloads as ``rows`` (built with ``reserved=HEADER_SIZE``), and per
    message its channel and log time (also its publish time)."""

    rows: Rows
    channels: npt.NDArray[np.uint16]
    log_times: npt.NDArray[np.int64]

    def __post_init__(self) -> None:
        if self.rows.reserved != HEADER_SIZE:
            raise ValueError(f"message rows must reserve {HEADER_SIZE} bytes for the record header")
        if not len(self.rows) == len(self.channels) == len(self.log_times):
            raise ValueError("a message block needs one channel and one time per row")
        if len(self.log_times) and int(self.log_times.min()) < 0:
            raise ValueError("MCAP log times are unsigned: a message before 1970")


@dataclass
class _OpenChunk:
    """Record bytes of the chunk being filled, with each message's offset, channel and time."""

    pieces: list[memoryview]
    size: int
    starts: list[npt.NDArray[np.int64]]
    channels: list[npt.NDArray[np.uint16]]
    log_times: list[npt.NDArray[np.int64]]

    @classmethod
    def empty(cls) -> _OpenChunk:
        return cls([], 0, [], [], [])


class ColumnarMcapWriter:
    """Writes an indexed, zstd-chunked MCAP file from blocks of messages.

    Errors of the worker (a full disk) are raised by the next call that waits for it:
    :meth:`write`, :meth:`flush` or :meth:`close`.
    """

    def __init__(self, file: BinaryIO, *, profile: str, library: str, chunk_size: int, level: int = 1) -> None:
        self._file = file
        self._chunk_size = chunk_size
        self._compressor = zstandard.ZstdCompressor(level=level)
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="mcap-writer")
        self._queued: deque[Future[None]] = deque()
        self._position = 0
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        #: Chunk Index records, serialised at once: a day's export has ten thousand chunks.
        self._chunk_indexes: list[bytes] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts = np.zeros(1, np.int64)
        self._times: tuple[int, int] | None = None
        self._sequence = 0
        self._open = _OpenChunk.empty()
        self._submit(lambda: self._put(MAGIC + _records(Header(profile=profile, library=library))))

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._submit(lambda: self._put(_records(schema)))
        return schema.id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        """A channel, written at once: before the chunk that holds its first message."""
        channel = Channel(
            id=len(self._channels) + 1,
            schema_id=schema_id,
            topic=topic,
            message_encoding=message_encoding,
            metadata=metadata,
        )
        self._channels.append(channel)
        self._counts = np.append(self._counts, 0)
        self._submit(lambda: self._put(_records(channel)))
        return channel.id

    def add_metadata(self, name: str, fields: dict[str, str]) -> None:
        self._submit(lambda: self._put_metadata(Metadata(name=name, metadata=fields)))

    def write(self, block: MessageBlock) -> None:
        """Messages in the order given; chunks are cut at ``chunk_size`` bytes of records."""
        count = len(block.rows)
        if count == 0:
            return
        self._fill_headers(block)
        self._counts += np.bincount(block.channels, minlength=len(self._counts))
        first, last = int(block.log_times.min()), int(block.log_times.max())
        self._times = (first, last) if self._times is None else (min(self._times[0], first), max(self._times[1], last))
        starts, view, done = block.rows.offsets, memoryview(block.rows.data), 0
        while done < count:
            room = self._chunk_size - self._open.size
            # Whole messages up to the chunk's size; at least one, into an empty chunk.
            end = int(np.searchsorted(starts, starts[done] + room, "right")) - 1
            end = min(max(end, done + (0 if self._open.size else 1)), count)
            if end > done:
                self._take(view, starts, block, done, end)
            if end < count:
                self._close_chunk()
            done = end

    def flush(self) -> None:
        """Writes the open chunk and waits until everything given so far is in the file."""
        self._close_chunk()
        self._submit(self._file.flush)
        self._wait(0)

    def close(self) -> None:
        """The summary section and footer; the file stays open (the caller closes it)."""
        try:
            self._close_chunk()
            self._submit(self._finish)
            self._wait(0)
        finally:
            self._worker.shutdown(wait=True, cancel_futures=True)

    # Main thread: building ---------------------------------------------------------------------

    def _fill_headers(self, block: MessageBlock) -> None:
        count, rows = len(block.rows), block.rows
        headers = np.zeros(count, MESSAGE_HEADER)
        headers["opcode"] = Opcode.MESSAGE
        headers["length"] = rows.lengths() - 9
        headers["channel"] = block.channels
        headers["sequence"] = (self._sequence + np.arange(count)) & 0xFFFFFFFF
        headers["log_time"] = block.log_times
        headers["publish_time"] = block.log_times
        self._sequence += count
        places = rows.offsets[:-1, None] + _HEADER_PLACES
        rows.buffer()[places] = headers.view(np.uint8).reshape(count, HEADER_SIZE)

    def _take(self, view: memoryview, starts: npt.NDArray[np.int64], block: MessageBlock, done: int, end: int) -> None:
        begin, stop = int(starts[done]), int(starts[end])
        self._open.pieces.append(view[begin:stop])
        self._open.starts.append(starts[done:end] - begin + self._open.size)
        self._open.channels.append(block.channels[done:end])
        self._open.log_times.append(block.log_times[done:end])
        self._open.size += stop - begin

    def _close_chunk(self) -> None:
        chunk, self._open = self._open, _OpenChunk.empty()
        if chunk.size:
            self._wait(MAX_QUEUED_CHUNKS)
            self._submit(lambda: self._put_chunk(chunk))

    # Worker thread: compressing and writing, in order -------------------------------------------

    def _submit(self, step: Callable[[], None]) -> None:
        self._queued.append(self._worker.submit(step))

    def _wait(self, queued: int) -> None:
        """Until at most ``queued`` steps wait; the first failure is raised here."""
        while len(self._queued) > queued:
            self._queued.popleft().result()

    def _put(self, data: bytes) -> None:
        self._file.write(data)
        self._position += len(data)

    def _put_metadata(self, metadata: Metadata) -> None:
        record = _records(metadata)
        self._metadata_indexes.append(MetadataIndex(offset=self._position, length=len(record), name=metadata.name))
        self._put(record)

    def _put_chunk(self, chunk: _OpenChunk) -> None:
        records = b"".join(chunk.pieces)
        starts, channels, times = (
            np.concatenate(chunk.starts),
            np.concatenate(chunk.channels),
            np.concatenate(chunk.log_times),
        )
        compressed = self._compressor.compress(records)
        first, last = int(times.min()), int(times.max())
        record = _records(
            Chunk(
                message_start_time=first,
                message_end_time=last,
                uncompressed_size=len(records),
                uncompressed_crc=zlib.crc32(records),
                compression="zstd",
                data=compressed,
            )
        )
        chunk_start = self._position
        self._put(record)
        index_start, offsets, indexes_size = self._position, {}, 0
        indexes = _message_indexes(starts, channels, times)
        for channel, index in indexes:
            offsets[channel] = index_start + indexes_size
            indexes_size += len(index)
        self._put(b"".join(index for _, index in indexes))
        self._chunk_indexes.append(
            _records(
                ChunkIndex(
                    message_start_time=first,
                    message_end_time=last,
                    chunk_start_offset=chunk_start,
                    chunk_length=len(record),
                    message_index_offsets=offsets,
                    message_index_length=self._position - index_start,
                    compression="zstd",
                    compressed_size=len(compressed),
                    uncompressed_size=len(records),
                )
            )
        )

    def _finish(self) -> None:
        self._put(_records(DataEnd(data_section_crc=0)))
        channel_counts = {channel.id: int(self._counts[channel.id]) for channel in self._channels}
        start, end = self._times or (0, 0)
        statistics = Statistics(
            message_count=int(self._counts.sum()),
            schema_count=len(self._schemas),
            channel_count=len(self._channels),
            attachment_count=0,
            metadata_count=len(self._metadata_indexes),
            chunk_count=len(self._chunk_indexes),
            message_start_time=start,
            message_end_time=end,
            channel_message_counts=channel_counts,
        )
        groups = (
            (Opcode.SCHEMA, _records(*self._schemas)),
            (Opcode.CHANNEL, _records(*self._channels)),
            (Opcode.STATISTICS, _records(statistics)),
            (Opcode.CHUNK_INDEX, b"".join(self._chunk_indexes)),
            (Opcode.METADATA_INDEX, _records(*self._metadata_indexes)),
        )
        summary_start, offsets, group_start = self._position, [], self._position
        for opcode, group in groups:
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=group_start, group_length=len(group)))
            group_start += len(group)
        summary = b"".join(group for _, group in groups) + _records(*offsets)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, group_start), zlib.crc32(summary))
        footer = Footer(summary_start=summary_start, summary_offset_start=group_start, summary_crc=crc)
        self._put(summary + _records(footer) + MAGIC)
        self._file.flush()


def _records(
    *records: Header | Schema | Channel | Metadata | Chunk | ChunkIndex | MetadataIndex | Statistics | SummaryOffset
    | DataEnd | Footer,
) -> bytes:
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    return bytes(builder.end())  # type: ignore[no-untyped-call]


def _message_indexes(
    starts: npt.NDArray[np.int64], channels: npt.NDArray[np.uint16], times: npt.NDArray[np.int64]
) -> list[tuple[int, bytes]]:
    """A Message Index record per channel: (log time, offset in the chunk) by time."""
    order = np.lexsort((times, channels))
    sorted_channels = channels[order]
    bounds = np.flatnonzero(np.diff(sorted_channels)) + 1
    indexes = []
    for group in np.split(order, bounds):
        entries = np.empty((len(group), 2), "<u8")
        entries[:, 0], entries[:, 1] = times[group], starts[group]
        channel = int(channels[group[0]])
        indexes.append(
            (
                channel,
                _MESSAGE_INDEX.pack(Opcode.MESSAGE_INDEX, 6 + entries.nbytes, channel, entries.nbytes)
                + entries.tobytes(),
            )
        )
    return indexes
