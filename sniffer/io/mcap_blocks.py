"""The native capture's block layout: what the messages of its topics hold, and how
chunks are cut into blocks. :mod:`sniffer.io.mcap_native` reads and writes the files.

One MCAP message on topic ``/rtusniff/raw_chunks`` carries a block of up to ``BLOCK_CHUNKS``
chunks and ``BLOCK_BYTES`` bytes in columns (little-endian)::

    u32 count | i64[count] t_end_ns | u32[count] length | bytes data

UART errors and channels travel on side topics (see :mod:`sniffer.io.mcap_native`). A chunk of
the file may claim at most ``max_block_bytes()`` uncompressed, which the reader checks before
decompressing it.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from decoders.capture import ChunkBatch

TOPIC = "/rtusniff/raw_chunks"
MESSAGE_ENCODING = "rtusniff.chunk-block.v1"
METADATA_NAME = "rtusniff.capture"
NOTES_METADATA_NAME = "rtusniff.notes"
PROFILE = "rtusniff"
FORMAT_VERSION = "1"
BLOCK_CHUNKS = 4096
#: Chunks of small blocks joined into one batch for the decoder, at most (see ``batches``).
BATCH_CHUNKS = 8192
#: A block holds at most this much line data (a single larger read stays one block).
BLOCK_BYTES = 16 * 2**20
#: What a chunk may claim uncompressed, unless the environment variable says otherwise (MiB).
MAX_BLOCK_MIB = 256
LIMIT_VARIABLE = "RTUSNIFF_MAX_BLOCK_MB"


def max_block_bytes() -> int:
    """The most a chunk may hold uncompressed: ``MAX_BLOCK_MIB``, or ``$RTUSNIFF_MAX_BLOCK_MB``."""
    given = os.environ.get(LIMIT_VARIABLE, "")
    return (int(given) if given.isdigit() and int(given) > 0 else MAX_BLOCK_MIB) * 2**20
#: How every MCAP file begins and ends.
MCAP_MAGIC = b"\x89MCAP0\r\n"
_COUNT = struct.Struct("<I")
LAYOUT_DOC = "u32 count | i64[count] t_end_ns | u32[count] length | bytes data (little-endian)"
ERRORS_TOPIC = "/rtusniff/uart_errors"
ERRORS_ENCODING = "rtusniff.uart-errors.v1"
CHANNELS_TOPIC = "/rtusniff/chunk_channels"
CHANNELS_ENCODING = "rtusniff.chunk-channels.v1"
CHANNELS_LAYOUT_DOC = "u32 count | u8[count] channel of each chunk of the next block (1-based into 'channels'; 0 none)"
ERRORS_LAYOUT_DOC = ("u32 count | u32[count] byte offset in the next block's data | u8[count] kind "
                     "(1 framing, 2 parity; little-endian)")
#: The side topics: encoding and layout.
SIDE_CHANNELS = {ERRORS_TOPIC: (ERRORS_ENCODING, ERRORS_LAYOUT_DOC),
                 CHANNELS_TOPIC: (CHANNELS_ENCODING, CHANNELS_LAYOUT_DOC)}
#: The topics a reader reads, and their encodings.
ENCODINGS = {TOPIC: MESSAGE_ENCODING, ERRORS_TOPIC: ERRORS_ENCODING, CHANNELS_TOPIC: CHANNELS_ENCODING}


def encode_block(batch: ChunkBatch) -> bytes:
    """One message payload for a batch of chunks."""
    lengths = np.diff(batch.ends, prepend=0).astype("<u4")
    return b"".join(
        [_COUNT.pack(len(batch)), batch.t_end_ns.astype("<i8").tobytes(), lengths.tobytes(), batch.data]
    )


def decode_block(payload: bytes) -> ChunkBatch:
    """The chunks of one message payload; ``ValueError`` if it is inconsistent."""
    if len(payload) < _COUNT.size:
        raise ValueError("block shorter than its header")
    (count,) = _COUNT.unpack_from(payload)
    data_start = _COUNT.size + 12 * count
    if len(payload) < data_start:
        raise ValueError(f"block announces {count} chunks but is only {len(payload)} bytes")
    times = np.frombuffer(payload, "<i8", count, _COUNT.size).astype(np.int64)
    lengths = np.frombuffer(payload, "<u4", count, _COUNT.size + 8 * count).astype(np.int64)
    ends = np.cumsum(lengths)
    if (int(ends[-1]) if count else 0) != len(payload) - data_start:
        raise ValueError("chunk lengths do not add up to the block's data")
    if count and bool((times[1:] < times[:-1]).any()):
        raise ValueError("chunk times decrease inside a block")
    return ChunkBatch(payload[data_start:], ends, times)


def longest_chunk(payload: bytes) -> int:
    """The length of the longest chunk of a block :func:`decode_block` took (its lengths as written)."""
    (count,) = _COUNT.unpack_from(payload)
    return int(np.frombuffer(payload, "<u4", count, _COUNT.size + 8 * count).max()) if count else 0


def encode_errors(kinds: npt.NDArray[np.uint8]) -> bytes:
    """The ``/rtusniff/uart_errors`` payload for a block's per-byte kinds."""
    offsets = np.flatnonzero(kinds)
    return b"".join([_COUNT.pack(len(offsets)), offsets.astype("<u4").tobytes(), kinds[offsets].tobytes()])


def side_messages(block: ChunkBatch) -> list[tuple[str, bytes]]:
    """What the side topics say about a block (written just before it): its UART errors and
    its chunks' channels, where it has them."""
    side = []
    if block.uart_errors is not None:
        side.append((ERRORS_TOPIC, encode_errors(block.uart_errors)))
    if block.channels is not None:
        side.append((CHANNELS_TOPIC, encode_channels(block.channels)))
    return side


def encode_channels(channels: npt.NDArray[np.uint8]) -> bytes:
    """The ``/rtusniff/chunk_channels`` payload for a block's chunk channels."""
    return _COUNT.pack(len(channels)) + channels.astype(np.uint8).tobytes()


def decode_channels(payload: bytes, count: int, names: int) -> npt.NDArray[np.uint8]:
    """The channels of a block of ``count`` chunks; ``ValueError`` if inconsistent."""
    if len(payload) != _COUNT.size + count or _COUNT.unpack_from(payload)[0] != count:
        raise ValueError(f"channels message does not hold one channel for each of the block's {count} chunks")
    channels = np.frombuffer(payload, np.uint8, count, _COUNT.size).copy()
    if count and int(channels.max()) > names:
        raise ValueError(f"channels message names channel {int(channels.max())} of {names}")
    return channels


def decode_errors(payload: bytes, size: int) -> npt.NDArray[np.uint8]:
    """Per-byte kinds of a block of ``size`` bytes from its errors payload; ``ValueError`` if
    it is inconsistent."""
    if len(payload) < _COUNT.size:
        raise ValueError("errors message shorter than its header")
    (count,) = _COUNT.unpack_from(payload)
    if len(payload) != _COUNT.size + 5 * count:
        raise ValueError(f"errors message announces {count} bytes but is {len(payload)} bytes long")
    offsets = np.frombuffer(payload, "<u4", count, _COUNT.size).astype(np.int64)
    marks = np.frombuffer(payload, np.uint8, count, _COUNT.size + 4 * count)
    if count and (int(offsets.max()) >= size or int(marks.min()) == 0 or int(marks.max()) > 3):
        raise ValueError("errors message names a byte outside its block or an unknown kind")
    kinds = np.zeros(size, np.uint8)
    kinds[offsets] = marks
    return kinds


def block_batches(batch: ChunkBatch) -> Iterator[ChunkBatch]:
    """A batch of chunks in blocks of at most ``BLOCK_CHUNKS`` chunks and ``BLOCK_BYTES`` bytes
    (or one chunk, when it alone is larger), one message each."""
    start = 0
    while start < len(batch):
        first_end = int(batch.ends[start - 1]) if start else 0
        stop = min(start + BLOCK_CHUNKS, len(batch))
        within = int(np.searchsorted(batch.ends[start:stop], first_end + BLOCK_BYTES, side="right"))
        stop = start + max(within, 1)
        yield batch.slice(start, stop)
        start = stop
