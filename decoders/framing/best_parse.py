"""One best parse of a run of bytes: frames, damaged frames and noise, by dynamic programming.

A *segment* is a run of bytes that timing could not split (no silence of t3.5 on an
exact capture; no gap of 3 s on a host one).
It may hold one frame or thousands (a master that never leaves t3.5, a host read
holding many frames), stray bytes, glitches and damaged frames. :func:`parse_segment`
cuts it into :class:`Piece` s covering every byte exactly once.

**The best parse.** Each candidate piece starting at a byte position -- a frame by
its length rule in either direction, a frame by CRC search, a USS telegram, a damaged
frame between supported boundaries, one noise byte -- carries a score from its
evidence (the weights: :mod:`decoders.framing.evidence`). Dynamic programming over
byte positions (Viterbi) finds the sequence of pieces covering every byte with the
highest total score (:mod:`decoders.framing.programme`).

**Anchors (the fast path).** A *clean* frame -- CRC-valid at its rule length, a
public function code, an address 1-247, one reading only (not also CRC-valid in the
other direction, nor, for an FC 8 echo of any length, at another length), no pause
inside, no other clean frame starting inside it -- that touches another clean frame
(up to ``ANCHOR_REACH`` stray bytes between them) or a supported boundary is on
every best parse: reading its bytes any other way gives up 16 bits of CRC evidence
per frame that no other reading can win back except by another CRC coincidence
(2^-16). Anchors are found for a whole segment at once by numpy
(:func:`decoders.framing.fast.clean_frame_ends`: the CRC of every candidate span
from prefix registers); short segments by a scalar pass. The dynamic programme runs
only over the bytes between anchors. ``fast=False`` runs it over the whole segment
instead: the plain reference path the tests hold the fast path to.

**Streaming.** Of an open segment (its end not yet known), pieces are committed up
to the last anchor whose confirmation is complete. When no anchor comes for
``WINDOW`` bytes, the programme runs over that window and commits up to the point
where the best paths to every position near the window's end agree (the common
ancestor of their tracebacks), so memory and delay stay bounded. The rest is parsed
later with ``Context.follows_frame`` where a valid frame was committed last: a frame ends
where it begins, as the parse of the whole segment would know.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache

import numpy as np
import numpy.typing as npt
from fastcrc import crc16

from decoders.capture import Int64Array
from decoders.frame import FrameFlag
from decoders.framing import evidence as ev
from decoders.framing.content import MAX_ADDRESS, MIN_ADU, OpenRequest, replayed_open_request
from decoders.framing.crossing import uncrossed
from decoders.framing.fast import clean_frame_ends
from decoders.framing.programme import MAX_EDGE, Context, Piece, Region, best_pieces, best_pieces_before_anchor
from decoders.framing.zero_end import weighed_zero_end
from decoders.modbus.layouts import MAX_ADU

#: Stray bytes allowed between two clean frames that confirm each other.
ANCHOR_REACH = 4
#: An open segment without anchors is parsed in windows of this many bytes.
WINDOW = 4 * MAX_ADU


@dataclass
class Pieces:
    """Pieces in columns, in wire order."""

    first: Int64Array
    last: Int64Array
    is_noise: npt.NDArray[np.bool_]
    crc_ok: npt.NDArray[np.bool_]
    flags: npt.NDArray[np.uint16]
    protocol: npt.NDArray[np.uint8]

    @classmethod
    def of(cls, pieces: list[Piece]) -> Pieces:
        rows = np.array([(p.start, p.end, p.is_noise, p.crc_ok, p.flags, p.protocol) for p in pieces],
                        np.int64).reshape(-1, 6)
        return cls(rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].astype(np.bool_), rows[:, 3].astype(np.bool_),
                   rows[:, 4].astype(np.uint16), rows[:, 5].astype(np.uint8))

    @classmethod
    def frames(cls, first: Int64Array, last: Int64Array) -> Pieces:
        """Valid Modbus frames ``[first[i], last[i])``."""
        count = len(first)
        return cls(first, last, np.zeros(count, np.bool_), np.ones(count, np.bool_), np.zeros(count, np.uint16),
                   np.zeros(count, np.uint8))

    @classmethod
    def join(cls, parts: list[Pieces]) -> Pieces:
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in _PIECE_COLUMNS))

    def shifted(self, offset: int) -> Pieces:
        """The pieces ``offset`` bytes on, in arrays of their own (a remembered parse's are shared)."""
        return Pieces(self.first + offset, self.last + offset, self.is_noise.copy(), self.crc_ok.copy(),
                      self.flags.copy(), self.protocol.copy())

    def in_order(self) -> Pieces:
        order = np.argsort(self.first, kind="stable")
        return Pieces(*(getattr(self, name)[order] for name in _PIECE_COLUMNS))

    def __len__(self) -> int:
        return len(self.first)

    def __iter__(self) -> Iterator[Piece]:
        columns = zip(*(getattr(self, name).tolist() for name in _PIECE_COLUMNS), strict=True)
        return (Piece(a, b, c, d, FrameFlag(e), f) for a, b, c, d, e, f in columns)


_PIECE_COLUMNS = ("first", "last", "is_noise", "crc_ok", "flags", "protocol")


@dataclass(slots=True)
class SegmentParse:
    """Pieces of a segment; ``consumed`` is how far they reach (all of it when closed);
    ``open_request`` is the request still awaiting its response after them."""

    pieces: Pieces
    consumed: int
    open_request: OpenRequest = None


def parse_segment(
    data: bytes, context: Context, open_request: OpenRequest = None, *, fast: bool = True
) -> SegmentParse:
    """Cut ``data`` into pieces: all of it when ``context.closed``, else up to where
    every surviving reading agrees (``consumed``)."""
    end = len(data)
    if not fast:
        if not context.closed:
            return SegmentParse(Pieces.of([]), 0, open_request)
        parse = best_pieces(Region(data, 0, end, context, ev.CrcSearch(data)), open_request)
        return SegmentParse(Pieces.of(parse.pieces), end, parse.open_request)
    weighed = weighed_zero_end(data, context, open_request)
    if weighed is not None:  # a frame ending in 0x00 or a shorter one and a glitch, nothing else
        glitch, open_request = weighed
        return SegmentParse(_weighed_pieces(end, glitch), end, open_request)
    search = ev.CrcSearch(data)
    readings: list[tuple[Int64Array, Int64Array]] | None = None
    if end < SMALL_SEGMENT:
        small_starts, small_stops = _anchors_small(data, context)
        anchor_starts, anchor_ends = np.array(small_starts, np.int64), np.array(small_stops, np.int64)
    else:
        readings = []
        anchor_starts, anchor_ends = _anchors_of(_clean_frames(data, search, readings), data, context)
    kept = uncrossed(data, context, search, (anchor_starts, anchor_ends), readings)
    if not kept.all():
        anchor_starts, anchor_ends = anchor_starts[kept], anchor_ends[kept]
    starts, stops = anchor_starts.tolist(), anchor_ends.tolist()
    pieces, open_request = _between_anchors(data, context, search, (starts, stops), open_request)
    position = stops[-1] if stops else 0
    if context.closed:
        if position < end:
            region = Region(data, position, end, context, search, after_frame=_after_frame(position, context))
            tail = best_pieces(region, open_request)
            pieces.extend(tail.pieces)
            open_request = tail.open_request
        position = end
    else:
        committed, position, open_request = _windows(data, context, search, position, open_request)
        pieces.extend(committed)
    if end < SMALL_SEGMENT:
        pieces.extend(Piece(a, b) for a, b in zip(starts, stops, strict=True))
        pieces.sort(key=lambda piece: piece.start)
        return SegmentParse(Pieces.of(pieces), position, open_request)
    if len(starts) < len(anchor_starts):  # the programme dropped some (crossing.py, rule 1)
        anchor_starts, anchor_ends = np.array(starts, np.int64), np.array(stops, np.int64)
    columns = Pieces.join([Pieces.frames(anchor_starts, anchor_ends), Pieces.of(pieces)]).in_order()
    return SegmentParse(columns, position, open_request)


@cache
def _weighed_pieces(size: int, glitch: bool) -> Pieces:
    """A segment of ``size`` bytes as one frame, or as a frame and a glitch byte (shared, as a
    remembered parse's pieces are: the framer shifts them into arrays of its own)."""
    if glitch:
        return Pieces.of([Piece(0, size - 1), Piece(size - 1, size, is_noise=True, crc_ok=False)])
    return Pieces.of([Piece(0, size)])


def _between_anchors(
    data: bytes, context: Context, search: ev.CrcSearch, anchors: tuple[list[int], list[int]],
    open_request: OpenRequest,
) -> tuple[list[Piece], OpenRequest]:
    """The programme's pieces between consecutive anchors (not the anchors themselves),
    and the open request after the last anchor. An anchor a reading from the gap before it
    crosses is none (:mod:`decoders.framing.crossing`, rule 1): it leaves ``anchors`` (lists,
    changed in place) and its bytes are parsed with the gap's."""
    starts, stops = anchors
    pieces: list[Piece] = []
    gaps = [k for k in range(len(starts)) if starts[k] > (stops[k - 1] if k else 0)]  # anchors after a gap
    since = 0  # anchors since the open request was last known: replayed only where needed
    dropped = 0  # anchors dropped so far: the indexes in ``gaps`` past them are this much less now
    taken = 0
    index: int | None = None
    while index is not None or taken < len(gaps):
        if index is None:
            index, taken = gaps[taken] - dropped, taken + 1
        position = stops[index - 1] if index else 0
        before = replayed_open_request(data, anchors, range(since, index), open_request)
        region = Region(data, position, starts[index], context, search, after_frame=_after_frame(position, context),
                        before_frame=True)
        gap = best_pieces_before_anchor(region, before)
        if gap is None:  # the anchor goes; the next one, if it touched it, ends the gap now
            del starts[index], stops[index]
            dropped += 1
            if index == len(starts) or (taken < len(gaps) and gaps[taken] - dropped == index):
                index = None
            continue
        pieces.extend(gap.pieces)
        open_request, since, index = gap.open_request, index, None
    return pieces, replayed_open_request(data, anchors, range(since, len(starts)), open_request)


def _windows(
    data: bytes, context: Context, search: ev.CrcSearch, position: int, open_request: OpenRequest
) -> tuple[list[Piece], int, OpenRequest]:
    """Of an open segment without anchors for ``WINDOW`` bytes from ``position``: the
    pieces every best path agrees on, window by window; where they end; the open request."""
    pieces: list[Piece] = []
    while len(data) - position > WINDOW:
        region = Region(data, position, position + WINDOW, context, search,
                        after_frame=_after_frame(position, context), open_end=True)
        window = best_pieces(region, open_request)
        if window.consumed == position:
            break
        pieces.extend(window.pieces)
        open_request, position = window.open_request, window.consumed
    return pieces, position, open_request


def _after_frame(position: int, context: Context) -> bool:
    """Whether a frame ends at ``position``: an anchor's end, or, at 0, one committed before
    (the parse of the rest of a segment weighs a glitch and a damaged frame there as the parse
    of the whole segment would)."""
    return position > 0 or context.follows_frame


def clean_frame_end(data: bytes, start: int, stop: int) -> int:
    """End of the clean frame starting at ``start`` (within ``stop``), or 0."""
    if stop - start < MIN_ADU or not 0 < data[start] <= MAX_ADDRESS:
        return 0
    found = 0
    for fixed, position, base in ev.CLEAN_RULES[data[start + 1]]:
        if fixed:
            length = fixed
        elif start + position < stop:
            length = base + data[start + position]
        else:
            continue
        if length <= stop - start and found != start + length and crc16.modbus(data[start : start + length]) == 0:
            if found:
                return 0  # both directions pass the CRC (a frame ending in 0x00): the programme decides
            found = start + length
    if found and ev.any_length_echo(data[start : start + 4]) and any(
            crc16.modbus(data[start:end]) == 0 and end != found
            for end in range(start + MIN_ADU, min(stop, start + MAX_ADU) + 1)):
        return 0  # an echo (FC 8, return query data) is CRC-valid at another length too: two readings
    return found


#: Below this many bytes, clean frames are found by a scalar loop (numpy's fixed cost is higher).
SMALL_SEGMENT = 256


def _anchors_small(data: bytes, context: Context) -> tuple[list[int], list[int]]:
    """What :func:`_anchors_of` finds, by one scalar pass (short segments)."""
    end = len(data)
    ends = [clean_frame_end(data, position, end) for position in range(end)]
    pauses = set(context.pauses)
    first: list[int] = []
    last: list[int] = []
    covered_to = 0
    for position, stop in enumerate(ends):
        if (stop and covered_to <= position and not any(ends[position + 1 : stop])
                and not any(q in pauses for q in range(position + 1, stop))):
            first.append(position)
            last.append(stop)
        covered_to = max(covered_to, stop)
    starts: list[int] = []
    stops: list[int] = []
    for k, (start, stop) in enumerate(zip(first, last, strict=True)):
        before = start == 0 or start in pauses or (k > 0 and start - last[k - 1] <= ANCHOR_REACH)
        after = stop in pauses or (stop == end and context.closed) or (
            k + 1 < len(first) and first[k + 1] - stop <= ANCHOR_REACH)
        if (before or after) and (context.closed or end - stop > MAX_EDGE):
            starts.append(start)
            stops.append(stop)
    return starts, stops


def _clean_frames(data: bytes, search: ev.CrcSearch,
                  readings: list[tuple[Int64Array, Int64Array]]) -> tuple[Int64Array, Int64Array]:
    """Clean frames that no other clean frame starts inside of or covers the start of
    (two readings that overlap are for the programme to weigh); the readings by rule found on
    the way into ``readings`` (:func:`~decoders.framing.fast.clean_frame_ends`)."""
    end = len(data)
    ends = clean_frame_ends(data, registers=search.registers, readings=readings)
    starts_before = np.zeros(end + 1, np.int64)
    np.cumsum(ends > 0, out=starts_before[1:])
    covered_to = np.zeros(end + 1, np.int64)  # covered_to[q]: the furthest end of a frame starting before q
    np.maximum.accumulate(ends, out=covered_to[1:])
    first = np.flatnonzero(ends)
    last = ends[first]
    kept = (starts_before[last] == starts_before[first + 1]) & (covered_to[first] <= first)
    return first[kept], last[kept]


def _anchors_of(
    clean: tuple[Int64Array, Int64Array], data: bytes, context: Context
) -> tuple[Int64Array, Int64Array]:
    """The clean frames on every best parse (see the module docstring): no pause inside,
    touching another one or a supported boundary."""
    first, last = clean
    end = len(data)
    pause_at = np.zeros(end + 1, np.bool_)
    if context.pauses:
        pause_at[list(context.pauses)] = True
        pauses_before = np.zeros(end + 2, np.int64)
        np.cumsum(pause_at, out=pauses_before[1:])
        quiet = pauses_before[last] == pauses_before[first + 1]
        first, last = first[quiet], last[quiet]
    before = (first == 0) | pause_at[first]
    before[1:] |= first[1:] - last[:-1] <= ANCHOR_REACH
    after = pause_at[last] | ((last == end) & context.closed)
    after[:-1] |= first[1:] - last[:-1] <= ANCHOR_REACH
    anchored = before | after
    if not context.closed:
        # Of an open segment, a frame near the end may still be read differently with bytes to come.
        anchored &= end - last > MAX_EDGE
    return first[anchored], last[anchored]
