"""What the native MCAP capture's records claim, checked before it is believed.

MCAP protects a chunk's content with a CRC, but neither its compressed frames' own size claims
nor metadata records: a zstd frame may declare gigabytes inside a chunk that declares 100
bytes, an lz4 frame declares nothing, and a bit flipped in the ``rtusniff.capture`` record turns
19200 Bd into 39200 without a trace. So:

* :func:`inflated`: a chunk is decompressed to at most the size it declares (which the reader has
  already held to its limit): a zstd frame that claims more is refused before it is inflated, one
  that claims nothing is inflated up to the declared size, lz4 likewise; one that holds more or
  less is damaged;
* :func:`sealed` / :func:`seal_fault`: rtusniff's metadata records carry ``sha256``, the digest of
  their other fields (each ``KEY=VALUE`` line, sorted, UTF-8), checked on read. A record without
  one (rtusniff before the seal) is read if every field is one rtusniff wrote then; an unknown
  field without a seal is damage (a flipped key).
"""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import replace

import zstandard
from mcap.records import Chunk

#: The field that holds a metadata record's digest.
SEAL = "sha256"
#: The fields of ``rtusniff.capture`` and ``rtusniff.notes`` written before the seal.
UNSEALED_FIELDS = frozenset({"format_version", "timing", "notes", "writer", "line", "channels"})


class InflateError(ValueError):
    """A chunk that does not decompress to the size it declares."""


def inflated(chunk: Chunk) -> Chunk:
    """``chunk`` uncompressed, producing no more than it declares."""
    if chunk.compression == "":
        return chunk
    limit = chunk.uncompressed_size
    if chunk.compression == "zstd":
        # decompress() allocates what the frame header claims, whatever the bound it is given:
        # a claim beyond the chunk's is refused before; without a claim the bound holds.
        claimed = zstandard.frame_content_size(chunk.data)
        if claimed > limit:
            raise InflateError(f"a chunk decompresses to more than the {limit:,} bytes it declares (its zstd frame "
                               f"claims {claimed:,})")
        try:
            data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=limit + 1)
        except zstandard.ZstdError as exc:  # damaged, or more than the bound without saying so
            raise InflateError(f"a chunk does not decompress to the {limit:,} bytes it declares (zstd: {exc})") \
                from None
    elif chunk.compression == "lz4":
        try:
            import lz4.frame  # type: ignore[import-untyped]  # noqa: PLC0415 - optional, as in the mcap library
        except ImportError:
            raise InflateError("an lz4 chunk, and the lz4 package is not installed (pip install lz4)") from None
        try:
            data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=limit + 1)
        except RuntimeError as exc:  # lz4's error for a damaged frame
            raise InflateError(f"a damaged lz4 chunk: {exc}") from None
    else:
        raise InflateError(f"a chunk compressed as {chunk.compression!r}, which rtusniff does not read")
    if len(data) != limit:
        said = "more than" if len(data) > limit else f"{len(data):,} bytes, not"
        raise InflateError(f"a chunk decompresses to {said} the {limit:,} bytes it declares")
    return replace(chunk, compression="", data=data)


def _digest(fields: dict[str, str]) -> str:
    lines = sorted(f"{key}={value}" for key, value in fields.items() if key != SEAL)
    return hashlib.sha256("\n".join(lines).encode("utf-8", "surrogatepass")).hexdigest()


def sealed(fields: dict[str, str]) -> dict[str, str]:
    """``fields`` with their digest."""
    return {**fields, SEAL: _digest(fields)}


def seal_fault(fields: dict[str, str]) -> str | None:
    """What is wrong with a record's seal; ``None`` when it holds (or an old record is plausible)."""
    if SEAL not in fields:
        unknown = sorted(set(fields) - UNSEALED_FIELDS)
        return f"holds a field {unknown[0]!r} rtusniff never writes, and no digest" if unknown else None
    # As bytes: compare_digest refuses str with characters outside ASCII (a damaged digest may hold them).
    if not hmac.compare_digest(fields[SEAL].encode("utf-8", "surrogatepass"), _digest(fields).encode()):
        return "does not match its sha256 digest"
    return None
