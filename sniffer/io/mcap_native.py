"""The native binary capture: raw chunks in an MCAP file.

One MCAP message on topic ``/rtusniff/raw_chunks`` carries a block of up to
``BLOCK_CHUNKS`` chunks in columns (little-endian)::

    u32 count | i64[count] t_end_ns | u32[count] length | bytes data

so a day-long capture is a few thousand messages and reading it is numpy work.

Characters the receiver found wrong (framing, parity: :class:`decoders.capture.UartError`)
travel on a second topic, ``/rtusniff/uart_errors``, registered only when a capture has
some: a message there, written just before the block it belongs to, carries::

    u32 count | u32[count] offset of the byte in the block's data | u8[count] kind

A capture of several lines (:attr:`decoders.capture.CaptureInfo.channels`, named in the
metadata's ``channels``, a JSON list) says each chunk's on a third topic,
``/rtusniff/chunk_channels``, a message just before its block: ``u32 count | u8[count] channel``.

A reader that knows only the first topic reads every byte as before (it skips the channels).
Line settings, timing quality and notes are the MCAP metadata record
``rtusniff.capture``, written before any block, so that a file cut short still
says how to read it. The file is read as a stream (no seeking), which also reads
files whose summary section was never written.
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
from collections.abc import Iterator
from dataclasses import replace
from typing import BinaryIO, cast

from mcap.exceptions import EndOfFile, McapError, RecordLengthLimitExceeded
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata
from mcap.records import Chunk as McapChunk
from mcap.stream_reader import StreamReader, breakup_chunk
from zstandard import ZstdError

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality, joined_batches
from decoders.line import LineSettings
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io.base import max_read_bytes, read_limit_message
from sniffer.io.following import GrowingFile
from sniffer.io.mcap_blocks import (
    BATCH_CHUNKS,
    BLOCK_BYTES,
    CHANNELS_TOPIC,
    ENCODINGS,
    ERRORS_TOPIC,
    FORMAT_VERSION,
    LAYOUT_DOC,
    LIMIT_VARIABLE,
    MCAP_MAGIC,
    MESSAGE_ENCODING,
    METADATA_NAME,
    NOTES_METADATA_NAME,
    PROFILE,
    SIDE_CHANNELS,
    TOPIC,
    block_batches,
    decode_block,
    decode_channels,
    decode_errors,
    encode_block,
    longest_chunk,
    max_block_bytes,
    side_messages,
)
from sniffer.io.mcap_checks import inflated, seal_fault, sealed
from sniffer.io.output_files import open_new
from sniffer.tool_version import tool_version


def info_metadata(info: CaptureInfo) -> dict[str, str]:
    """The ``rtusniff.capture`` metadata record's fields."""
    fields = {
        "format_version": FORMAT_VERSION,
        "timing": info.timing.value,
        "notes": json.dumps(list(info.notes)),
        "writer": tool_version(),
    }
    if info.line is not None:
        fields["line"] = info.line.format()
    if info.channels:
        fields["channels"] = json.dumps(list(info.channels))
    if info.first_index:
        fields["first_frame"] = str(info.first_index)
    return sealed(fields)


class McapCaptureWriter:
    """Streams blocks of chunks into a zstd-compressed, indexed MCAP file.

    Every block is its own MCAP chunk, written out at once, so that :meth:`flush`
    makes everything written so far durable: a recording killed after a flush reads
    back up to it.
    """

    def __init__(self, path: str, info: CaptureInfo) -> None:
        # Imported here: it imports importlib.metadata, which would slow the start of every
        # command that reads an MCAP capture.
        from mcap.writer import CompressionType, Writer  # noqa: PLC0415

        self._file: BinaryIO = open_new(path)
        self._writer = Writer(self._file, compression=CompressionType.ZSTD, chunk_size=1)
        self._writer.start(profile=PROFILE, library=tool_version())
        self._writer.add_metadata(METADATA_NAME, info_metadata(info))
        self._channel = self._writer.register_channel(
            topic=TOPIC, message_encoding=MESSAGE_ENCODING, schema_id=0, metadata={"layout": LAYOUT_DOC}
        )
        #: The side topics' channels, registered when first needed (a plain capture has none).
        self._side_channels: dict[str, int] = {}
        self._sequence = 0
        # The header and the line settings are on disk at once: a capture killed before its
        # first block still says what it is (and reads as a capture without bytes).
        self.flush()

    def write_batch(self, batch: ChunkBatch) -> None:
        for block in block_batches(batch):
            t_first = int(block.t_end_ns[0])
            for topic, payload in side_messages(block):
                self._add(self._side_channel(topic), t_first, payload)
            self._add(self._channel, t_first, encode_block(block))

    def _add(self, channel: int, t_ns: int, payload: bytes) -> None:
        self._writer.add_message(channel_id=channel, log_time=t_ns, publish_time=t_ns, data=payload,
                                 sequence=self._sequence)
        self._sequence += 1

    def _side_channel(self, topic: str) -> int:
        if topic not in self._side_channels:
            encoding, layout = SIDE_CHANNELS[topic]
            self._side_channels[topic] = self._writer.register_channel(
                topic=topic, message_encoding=encoding, schema_id=0, metadata={"layout": layout})
        return self._side_channels[topic]

    def add_notes(self, notes: list[str]) -> None:
        if notes:
            self._writer.add_metadata(NOTES_METADATA_NAME, sealed({"notes": json.dumps(notes)}))

    def flush(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())

    @property
    def size(self) -> int:
        """Bytes written so far."""
        return self._file.tell()

    def close(self) -> None:
        self._writer.finish()  # type: ignore[no-untyped-call]
        self._file.close()

    def abandon(self) -> None:
        with contextlib.suppress(OSError):
            self._file.close()


class McapCaptureReader:
    """Reads the metadata at open; :meth:`batches` decodes the blocks in file order."""

    def __init__(self, path: str, *, follow: bool = False, line_given: bool = False) -> None:
        self.path = path
        self._follow = follow
        self._line_given = line_given
        #: Said once reading is done: e.g. a recording that was cut short.
        self.warnings: list[str] = []
        self._file: BinaryIO = (cast(BinaryIO, GrowingFile(path, warnings=self.warnings)) if follow
                                else open(path, "rb"))  # noqa: SIM115
        self._size = os.fstat(self._file.fileno()).st_size
        # A damaged length field must not make the reader allocate gigabytes: no record is
        # longer than the file (a file that grows: than a block may be).
        # CRCs checked: a bit flipped in a chunk is an error, never different frames read as good.
        # Chunks come whole (emit_chunks): their declared size is checked before they are decompressed.
        size_limit = 2 * max_block_bytes() if follow else max(self._size, 1)
        self._records = StreamReader(self._file, validate_crcs=True, record_size_limit=size_limit,
                                     emit_chunks=True).records
        #: The topics read (``ENCODINGS``) by channel id.
        self._topics: dict[int, str] = {}
        #: The last chunk's time so far: times never decrease, and none is before 1970.
        self._last_ns = 0
        self._good = 0
        self.late_notes: list[str] = []
        self.info = self._read_info()

    def close(self) -> None:
        self._file.close()

    def last_time_ns(self) -> int | None:
        """The last message's time, from the summary section (none in a recording cut short)."""
        try:
            with open(self.path, "rb") as summary_file:
                summary = make_reader(summary_file).get_summary()
        except Exception:
            return None
        if summary is None or summary.statistics is None or not summary.statistics.message_count:
            return None
        return int(summary.statistics.message_end_time)

    def _error(self, message: str) -> CaptureFormatError:
        return CaptureFormatError(
            ErrorKind.BAD_MCAP, message, path=self.path, location=f"byte {self._file.tell()}"
        )

    def _next_records(self) -> Iterator[object]:
        try:
            for record in self._records:
                if isinstance(record, McapChunk):
                    yield from breakup_chunk(inflated(self._checked(record)), validate_crc=True)
                else:
                    yield record
                self._good = self._file.tell()
        except (McapError, ValueError, struct.error, EOFError, OverflowError, MemoryError, ZstdError) as exc:
            if self._follow and cast(GrowingFile, self._file).stopped:
                return  # following was stopped inside a record being written: read up to it
            if self._good == self._size and self._good > 0:
                # Complete records up to the end, but no summary: a recording that was
                # killed or lost its disk after its last flush. Everything in it is read.
                self.warnings.append(
                    f"{self.path}: recording cut short at byte {self._size} (no closing summary); "
                    "everything up to its last flush was read"
                )
                return
            at_end = self._file.tell() >= self._size
            if self._good > 0 and not self._ends_whole():
                # The file ends inside a record: a copy or a download cut short, a recording
                # killed mid-write. What came before is whole (chunk CRCs checked): read it.
                self.warnings.append(
                    f"{self.path}: cut short at byte {self._good} of {self._size} (the record there runs past the "
                    "end of the file: truncated, or its length is damaged); everything before it was read"
                )
                return
            damage = _damage(exc, at_end=at_end)
            raise CaptureFormatError(
                ErrorKind.BAD_MCAP, f"damaged MCAP: {damage}", path=self.path, location=f"byte {self._good}"
            ) from None

    def _checked(self, chunk: McapChunk) -> McapChunk:
        """``chunk``, if what it says it holds uncompressed is within :func:`max_block_bytes`: a
        few kilobytes of zstd can claim gigabytes (a damaged or a hostile file)."""
        limit = max_block_bytes()
        if chunk.uncompressed_size > limit:
            raise CaptureFormatError(
                ErrorKind.BAD_MCAP, f"an MCAP chunk claims {chunk.uncompressed_size:,} bytes uncompressed, more than "
                f"rtusniff reads at once ({limit // 2**20} MiB; rtusniff writes at most {BLOCK_BYTES // 2**20} MiB "
                f"a block): a damaged or hostile file. {LIMIT_VARIABLE}=N (MiB) raises the limit",
                path=self.path, location=f"byte {self._good}")
        return chunk

    def _ends_whole(self) -> bool:
        """Whether the file ends as an MCAP file does (its closing magic): then damage inside it is
        damage, not a file cut short."""
        with open(self.path, "rb") as tail:
            tail.seek(max(self._size - len(MCAP_MAGIC), 0))
            return tail.read() == MCAP_MAGIC

    def _read_info(self) -> CaptureInfo:
        self._iter = self._next_records()
        for record in self._iter:
            if isinstance(record, Metadata) and record.name == METADATA_NAME:
                return self._parse_info(record.metadata)
            if isinstance(record, Message):
                break
        else:
            if self.warnings:  # the file ended inside a record, before the metadata
                raise CaptureFormatError(ErrorKind.BAD_MCAP, f"cut short at byte {self._good}, before its "
                                         f"'{METADATA_NAME}' metadata: nothing to read", path=self.path,
                                         location=f"byte {self._good}")
        raise self._error(
            f"not an rtusniff capture: no '{METADATA_NAME}' metadata before the first message "
            "(an MCAP written by another tool?)"
        )

    def _check_seal(self, fields: dict[str, str], name: str) -> None:
        """A metadata record whose seal fails is damage (:mod:`sniffer.io.mcap_checks`); with
        ``--line`` the capture's data is still read, the user told what cannot be trusted."""
        fault = seal_fault(fields)
        if fault is None:
            return
        if self._line_given:
            self.warnings.append(f"{self.path}: the '{name}' metadata is damaged ({fault}): read with --line as given; "
                                 "its timing, notes and channel names may be wrong")
            return
        raise self._error(f"damaged MCAP: the '{name}' metadata record {fault} (a flipped bit: the line settings, "
                          "timing and notes cannot be trusted); give --line to read the data anyway")

    def _parse_info(self, fields: dict[str, str]) -> CaptureInfo:
        self._check_seal(fields, METADATA_NAME)
        if fields.get("format_version") != FORMAT_VERSION:
            raise CaptureFormatError(
                ErrorKind.UNKNOWN_FORMAT,
                f"capture format version {fields.get('format_version')!r} is not {FORMAT_VERSION!r}",
                path=self.path,
            )
        try:
            line = LineSettings.parse(fields["line"]) if "line" in fields else None
            timing = TimingQuality(fields.get("timing", ""))
            notes = self._texts(fields.get("notes", "[]"), f"'{METADATA_NAME}' notes")
            channels = self._texts(fields.get("channels", "[]"), f"'{METADATA_NAME}' channels")
            first = fields.get("first_frame", "0")
            if not (first.isascii() and first.isdigit()) or len(first) > 18:
                raise ValueError(f"first_frame {first[:40]!r} is not a frame number")
        except (ValueError, TypeError) as exc:
            raise self._error(f"bad '{METADATA_NAME}' metadata: {exc}") from None
        return CaptureInfo(line=line, timing=timing, notes=notes, channels=channels, first_index=int(first))

    def batches(self) -> Iterator[ChunkBatch]:
        """The capture's chunks in batches of whole blocks: small blocks (a recording flushes one
        every second) are joined up to ``BATCH_CHUNKS`` chunks or ``BLOCK_BYTES`` bytes, since each
        batch costs the decoder a fixed overhead (thousands of one-chunk batches cost it dearly).
        Following, each block goes at once (:class:`~sniffer.io.following.FollowingReader` joins
        the blocks that are there already): no block is empty, so one chunk is enough."""
        return joined_batches(self._blocks(), 1 if self._follow else BATCH_CHUNKS, BLOCK_BYTES)

    def _blocks(self) -> Iterator[ChunkBatch]:
        #: What the side topics say about the next block, by topic.
        pending: dict[str, bytes] = {}
        for record in self._iter:
            if isinstance(record, Channel) and record.topic in ENCODINGS:
                if record.message_encoding != ENCODINGS[record.topic]:
                    raise self._error(f"channel {record.topic} has unknown encoding {record.message_encoding!r}")
                self._topics[record.id] = record.topic
            elif isinstance(record, Message) and record.channel_id in self._topics:
                topic = self._topics[record.channel_id]
                if topic != TOPIC:
                    pending[topic] = record.data
                    continue
                batch = self._block(record, pending)
                pending = {}
                if len(batch):
                    yield batch
            elif isinstance(record, Metadata) and record.name == NOTES_METADATA_NAME:
                self._check_seal(record.metadata, NOTES_METADATA_NAME)
                self.late_notes.extend(self._texts(record.metadata.get("notes", "[]"), f"'{NOTES_METADATA_NAME}'"))

    def _texts(self, text: str, what: str) -> tuple[str, ...]:
        """A metadata field that holds a JSON list of strings (notes, channel names)."""
        try:
            values = json.loads(text)
        except (ValueError, RecursionError):  # RecursionError: '[' nested thousands deep
            values = None
        if not isinstance(values, list) or not all(isinstance(value, str) for value in values):
            raise self._error(f"bad {what}: not a JSON list of strings")
        for value in values:
            try:
                value.encode("utf-8")
            except UnicodeEncodeError as error:  # "\ud800" in the JSON: no character, no output can write it
                raise self._error(f"bad {what}: {error.object[error.start]!r} is a lone surrogate, not text") from None
        return tuple(values)

    def _block(self, record: Message, side: dict[str, bytes]) -> ChunkBatch:
        """A block's chunks, with the UART errors and channels its side messages give."""
        try:
            batch = decode_block(record.data)
            largest = longest_chunk(record.data)
            if largest > max_read_bytes():
                raise self._error(read_limit_message(largest))
            if ERRORS_TOPIC in side:
                batch = replace(batch, uart_errors=decode_errors(side[ERRORS_TOPIC], len(batch.data)))
            if CHANNELS_TOPIC in side:
                channels = decode_channels(side[CHANNELS_TOPIC], len(batch), len(self.info.channels))
                batch = replace(batch, channels=channels)
            if len(batch) and int(batch.t_end_ns[0]) < 0:
                raise ValueError("a time before 1970 (negative)")
            if len(batch) and int(batch.t_end_ns[0]) < self._last_ns:
                raise ValueError("its first chunk is earlier than the last chunk of the block before "
                                 "(times must not decrease)")
        except ValueError as exc:
            raise self._error(f"bad chunk block (sequence {record.sequence}): {exc}") from None
        if len(batch):
            self._last_ns = int(batch.t_end_ns[-1])
        return batch


def _damage(exc: Exception, *, at_end: bool) -> str:
    if at_end or isinstance(exc, (EndOfFile, EOFError, RecordLengthLimitExceeded)):
        return "a record runs past the end of the file (truncated, or its length is damaged)"
    return str(exc) or type(exc).__name__
