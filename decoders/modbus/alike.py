"""Which frames kept in columns read alike, so that each group is named and spelt once.

Half the frames of a batch of mixed traffic, and nearly all of steady traffic, repeat one
another: a request polled again, a drive's unchanged status. :func:`alike` groups the frames of
:class:`~decoders.modbus.columnar.ColumnarFrames` whose texts are the same; profiles name the
first of each group (:func:`~decoders.profiles.column_names.named`) and the decoded form gives it
once (:class:`~decoders.decoded_batch.InColumns`), the others sharing what was made. For frames
decoded one by one the annotator's memo does that, within a batch and across batches.

How, and why so:

* Frames are grouped by a number mixed of their digest (:func:`digests`: CRC, length, slave and
  function) and of their role, kind, first address and count. Each is then compared
  with its group's first, byte for byte (8 bytes at a time, :func:`_same_bytes`) and in all of
  those; those that differ (frames whose digests agree, as frames of a bus polled for a day do
  now and then) are grouped again among themselves, until every frame is alike its group's first.
* The grouping sorts the numbers (numpy's quicksort, the first of each group the least place
  among its equals: faster than the stable sort ``np.unique`` makes for its firsts).
* Where a sample of the frames shows them mostly distinct (random values polled), no grouping:
  there telling them apart costs more than it saves.

"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct
from decoders.hashing import FIBONACCI_SIGNED
from decoders.modbus.columnar import Alike, ColumnarFrames

if TYPE_CHECKING:
    from decoders.message import MessageBatch

#: The share of frames kept in columns, distinct at first sight, from which :func:`alike` leaves
#: them all to be spelt.
DISTINCT_SHARE = 0.9
#: Frames :func:`alike` samples to tell whether to look further.
SAMPLED = 512
_ALL_BYTES = np.uint64(0xFFFF_FFFF_FFFF_FFFF)


def alike(columnar: ColumnarFrames, data: bytes, offsets: npt.NDArray[np.int64],
          roles: npt.NDArray[np.integer[Any]]) -> Alike | None:
    """The frames of ``columnar`` whose texts are the same: alike in their bytes, role, kind,
    first address and count (an answer's are its request's); whatever else a text says (a
    profile's names) the batch holds for all its frames alike (the annotator cuts a batch where
    the profiles change, :mod:`decoders.profiles.columns`). ``offsets``,
    ``roles``: the batch's frames'. ``None`` where at least :data:`DISTINCT_SHARE` of a sample of
    the frames (every n-th, :data:`SAMPLED` of them) differ in their digest."""
    positions = columnar.positions
    if len(positions) < 2:
        return None
    starts, ends = offsets[positions], offsets[positions + 1]
    lengths = ends - starts
    step = max(len(positions) // SAMPLED, 1)
    if len(distinct(digests(data, starts[::step], ends[::step]))) >= DISTINCT_SHARE * len(starts[::step]):
        return None
    role = roles[positions].astype(np.int64)
    code = (role << 3 | columnar.kind) << 48 | (columnar.count + 1) << 24 | columnar.address
    with np.errstate(over="ignore"):  # mixed, wrapping: frames alike have it alike
        # The digest spread (Fibonacci hashing) before its role, kind, address and count are mixed in.
        mixed = digests(data, starts, ends) * FIBONACCI_SIGNED ^ code
    first = _group_firsts(np.arange(len(positions)), mixed)
    pending = np.flatnonzero(first != np.arange(len(first)))
    while len(pending):
        # Against the group's first; those that differ are grouped again among themselves.
        theirs = first[pending]
        differ = (code[pending] != code[theirs]) | (lengths[pending] != lengths[theirs])
        same_length = np.flatnonzero(~differ)
        differ[same_length] = ~_same_bytes(data, starts[pending[same_length]], starts[theirs[same_length]],
                                           lengths[pending[same_length]])
        lone = pending[differ]
        first[lone] = _group_firsts(lone, mixed)
        pending = lone[first[lone] != lone]
    is_first = first == np.arange(len(first))
    # Each group's row among the firsts: the number of firsts up to its first (a search of the
    # firsts for each frame cost twice what grouping them did).
    row = np.cumsum(is_first) - 1
    return Alike(np.flatnonzero(is_first), row[first])


def _group_firsts(rows: npt.NDArray[np.int64], key: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """For each of ``rows`` (ascending), the first of them with its ``key``: the keys sorted
    (not stably), the least place among equal keys is their first."""
    keys = key[rows]
    order = np.argsort(keys)
    ordered = keys[order]
    new = np.empty(len(ordered), np.bool_)
    new[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=new[1:])
    firsts = np.minimum.reduceat(order, np.flatnonzero(new)) if len(order) else order
    found = np.empty(len(order), np.int64)
    found[order] = firsts[np.cumsum(new) - 1]
    first: npt.NDArray[np.int64] = rows[found]
    return first


def _same_bytes(data: bytes, starts: npt.NDArray[np.int64], other_starts: npt.NDArray[np.int64],
                lengths: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """Whether ``data[start : start + length]`` and ``data[other : other + length]`` hold the
    same bytes, for each: compared 8 bytes at a time, each the 64-bit word that starts there
    (a view of the data with a stride of one byte; the last word's bytes past the length
    masked). Byte by byte, a million frames' bytes cost five times as much."""
    padded = np.zeros(len(data) + 8, np.uint8)  # the last word of the last frame reads past the data
    padded[: len(data)] = np.frombuffer(data, np.uint8)
    words = np.ndarray((len(data),), "<u8", padded, 0, (1,))
    same = np.ones(len(lengths), np.bool_)
    for offset in range(0, int(lengths.max(initial=0)), 8):
        rows = np.flatnonzero(lengths > offset)  # with bytes left to compare
        left = lengths[rows] - offset
        # Little-endian: a word's first bytes are its low ones.
        kept = np.where(left >= 8, _ALL_BYTES, (np.uint64(1) << (8 * np.minimum(left, 7)).astype(np.uint64)) - 1)
        same[rows] &= ((words[starts[rows] + offset] ^ words[other_starts[rows] + offset]) & kept) == 0
    return same


def digests(data: bytes, starts: npt.NDArray[np.int64], ends: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """A number per frame (``data[start:end]``) that frames alike share and frames that differ
    seldom do: its CRC (last two bytes), length, slave and function (first two bytes). A frame
    of fewer than two bytes reads its neighbours' or the data's last (no copy of the data is
    made to pad it); frames alike then differ in it at worst, and are only
    spelt apart. Only those bytes are widened to 64 bits."""
    raw = np.frombuffer(data, np.uint8)
    if not len(raw):  # frames of no bytes read a zero
        raw = np.zeros(1, np.uint8)
    top = len(raw) - 1

    def byte(at: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        return raw[at].astype(np.int64)

    last = byte(np.clip(ends - 1, 0, top)) << 8 | byte(np.clip(ends - 2, 0, top))
    first = byte(np.minimum(starts, top)) | byte(np.minimum(starts + 1, top)) << 8
    digest: npt.NDArray[np.int64] = last | (ends - starts) << 16 | first << 32
    return digest


def mostly_distinct(batch: MessageBatch, share: float) -> bool:
    """Whether at least ``share`` of the batch's frames differ from one another, as told by
    their CRC, length, slave and function (:func:`digests`)."""
    frames = batch.frames
    if not len(batch):
        return False
    return len(distinct(digests(frames.data, frames.offsets[:-1], frames.offsets[1:]))) >= share * len(batch)
