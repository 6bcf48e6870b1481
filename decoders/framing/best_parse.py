"""One best parse of a run of bytes: frames, damaged frames and noise, by dynamic programming.

A *segment* is a run of bytes that timing could not split (no silence of t3.5 on an
exact capture; no gap longer than the capture's own delivery delay on a host one).
It may hold one frame or thousands (a master that never leaves t3.5, a host read
holding many frames), stray bytes, glitches and damaged frames. :func:`parse_segment`
cuts it into :class:`Piece` s covering every byte exactly once.

**The best parse.** Each candidate piece starting at a byte position -- a frame by
its length rule in either direction, a frame by CRC search, a USS telegram, a damaged
frame between supported boundaries, one noise byte -- carries a score from its
evidence (the weights: :mod:`decoders.framing.evidence`). Dynamic programming over
byte positions (Viterbi) finds the sequence of pieces covering every byte with the
highest total score.

**Anchors (the fast path).** A *clean* frame -- CRC-valid at its rule length, a
public function code, an address 1-247, one reading only (not also CRC-valid in
the other direction), no pause inside, no other clean frame starting inside it -- that touches another clean frame (up to ``ANCHOR_REACH`` stray
bytes between them) or a supported boundary is on every best parse: reading its
bytes any other way gives up 16 bits of CRC evidence per frame that no other
reading can win back except by another CRC coincidence (2^-16). Anchors are found
by a scan that costs one or two CRC calls per frame; the dynamic programme runs
only over the bytes between anchors. ``fast=False`` runs it over the whole segment
instead: the plain reference path the tests hold the fast path to.

**Streaming.** Of an open segment (its end not yet known), pieces are committed up
to the last anchor whose confirmation is complete. When no anchor comes for
``WINDOW`` bytes, the programme runs over that window and commits up to the point
where the best paths to every position near the window's end agree (the common
ancestor of their tracebacks), so memory and delay stay bounded.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from fastcrc import crc16

from decoders.capture import Int64Array
from decoders.frame import MODBUS, FrameFlag
from decoders.framing import evidence as ev
from decoders.framing.content import after_frame
from decoders.framing.fast import clean_frame_ends
from decoders.modbus.layouts import MAX_ADU

OpenRequest = ev.OpenRequest
#: Stray bytes allowed between two clean frames that confirm each other.
ANCHOR_REACH = 4
#: The longest piece the programme can take, with a stray byte on either side.
MAX_EDGE = MAX_ADU + 2
#: An open segment without anchors is parsed in windows of this many bytes.
WINDOW = 4 * MAX_ADU


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes ``[start, end)`` of a segment: a frame, or noise."""

    start: int
    end: int
    is_noise: bool = False
    crc_ok: bool = True
    flags: FrameFlag = FrameFlag.NONE
    protocol: int = MODBUS


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
        return Pieces(self.first + offset, self.last + offset, self.is_noise, self.crc_ok, self.flags, self.protocol)

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


@dataclass(frozen=True, slots=True)
class Context:
    """What the parse of a segment knows beyond its bytes."""

    #: Positions (relative to the segment) whose byte follows a silence > t1.5; empty on host timing.
    pauses: tuple[int, ...] = ()
    closed: bool = True
    at_capture_start: bool = False
    at_capture_end: bool = False
    #: Timing closes the segment on both sides (a hard cut before and after it).
    timed: bool = False


def parse_segment(
    data: bytes, context: Context, open_request: OpenRequest = None, *, fast: bool = True
) -> SegmentParse:
    """Cut ``data`` into pieces: all of it when ``context.closed``, else up to where
    every surviving reading agrees (``consumed``)."""
    end = len(data)
    if not fast:
        if not context.closed:
            return SegmentParse(Pieces.of([]), 0, open_request)
        parse = _programme(data, 0, end, context, open_request, start_after_frame=False, end_before_frame=False)
        return SegmentParse(Pieces.of(parse.pieces), end, parse.open_request)
    small = end < SMALL_SEGMENT
    if small:
        starts, stops = _anchors_small(data, context)
        anchor_starts = anchor_ends = np.zeros(0, np.int64)
    else:
        anchor_starts, anchor_ends = _anchors_of(_clean_frames(data, context), data, context)
        starts, stops = anchor_starts.tolist(), anchor_ends.tolist()
    pieces: list[Piece] = []
    previous_ends = [0, *stops]
    # Anchors since the open request was last known; it is replayed only where needed.
    since = 0
    gaps = [k for k in range(len(starts)) if starts[k] > previous_ends[k]] if small else (
        np.flatnonzero(anchor_starts > np.array(previous_ends[:-1], np.int64)).tolist())
    for index in gaps:
        position = previous_ends[index]
        open_request = _replayed(data, starts, stops, since, index, open_request)
        gap = _programme(data, position, starts[index], context, open_request,
                         start_after_frame=position > 0, end_before_frame=True)
        pieces.extend(gap.pieces)
        open_request, since = gap.open_request, index
    open_request = _replayed(data, starts, stops, since, len(starts), open_request)
    position = previous_ends[-1]
    if context.closed:
        if position < end:
            tail = _programme(data, position, end, context, open_request,
                              start_after_frame=position > 0, end_before_frame=False)
            pieces.extend(tail.pieces)
            open_request = tail.open_request
        position = end
    else:
        while end - position > WINDOW:
            window = _programme(data, position, position + WINDOW, context, open_request,
                                start_after_frame=position > 0, end_before_frame=False, open_end=True)
            if window.consumed == position:
                break
            pieces.extend(window.pieces)
            open_request, position = window.open_request, window.consumed
    if small:
        pieces.extend(Piece(a, b) for a, b in zip(starts, stops, strict=True))
        pieces.sort(key=lambda piece: piece.start)
        return SegmentParse(Pieces.of(pieces), position, open_request)
    columns = Pieces.join([Pieces.frames(anchor_starts, anchor_ends), Pieces.of(pieces)]).in_order()
    return SegmentParse(columns, position, open_request)


def clean_frame_end(data: bytes, start: int, stop: int) -> int:
    """End of the clean frame starting at ``start`` (within ``stop``), or 0."""
    if stop - start < ev.MIN_ADU or not 0 < data[start] <= ev.MAX_SLAVE_ADDRESS:
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
    return found


#: How many frames back the open request is replayed from (only a run of echo frames
#: longer than this could make it differ from replaying them all).
REPLAY_FRAMES = 4


def _replayed(
    data: bytes, starts: list[int], stops: list[int], begin: int, stop: int, open_request: OpenRequest
) -> OpenRequest:
    """The open request after the whole frames ``begin..stop-1``."""
    if stop - begin > REPLAY_FRAMES:
        begin, open_request = stop - REPLAY_FRAMES, None
    for k in range(begin, stop):
        open_request = after_frame(data[starts[k] : stops[k]], open_request)
    return open_request


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


def _clean_frames(data: bytes, context: Context) -> tuple[Int64Array, Int64Array]:
    """Clean frames that no other clean frame starts inside of or covers the start of
    (two readings that overlap are for the programme to weigh)."""
    end = len(data)
    ends = clean_frame_ends(data)
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


def _pauses_in(pauses: tuple[int, ...], start: int, stop: int) -> int:
    return bisect_left(pauses, stop) - bisect_right(pauses, start)


@dataclass(slots=True)
class _Edge:
    start: int
    end: int
    kind: int  # _FRAME, _DAMAGED or _NOISE
    flags: FrameFlag = FrameFlag.NONE
    protocol: int = MODBUS


@dataclass(slots=True)
class _Parse:
    pieces: list[Piece]
    consumed: int
    open_request: OpenRequest


_FRAME, _DAMAGED, _NOISE = 0, 1, 2
_NEVER = float("-inf")


def _programme(
    data: bytes, begin: int, stop: int, context: Context, open_request: OpenRequest, *,
    start_after_frame: bool, end_before_frame: bool, open_end: bool = False,
) -> _Parse:
    """The best parse of ``data[begin:stop]`` (see the module docstring); with
    ``open_end``, only the part every best path to the last positions agrees on."""
    pauses = context.pauses
    pause_set = set(pauses)
    segment_end = len(data)
    closed_at_stop = not open_end and (stop < segment_end or context.closed)
    frames = [_valid_at(data, s, stop, begin, context, pause_set) for s in range(begin, stop)]
    frame_starts = [s for s in range(begin, stop) if frames[s - begin]]
    size = stop - begin
    best = [_NEVER] * (size + 1)
    back: list[_Edge | None] = [None] * (size + 1)
    requests: list[OpenRequest] = [None] * (size + 1)
    best[0], requests[0] = 0.0, open_request
    frame_ends = {begin} if start_after_frame else set()

    def supported(position: int) -> float:
        if position in pause_set or (position == stop and closed_at_stop):
            return ev.BOUNDARY_SUPPORTED
        return 0.0

    def offer(edge: _Edge, score: float) -> None:
        target = edge.end - begin
        if score > best[target]:
            best[target], back[target] = score, edge
            requests[target] = (after_frame(data[edge.start : edge.end], requests[edge.start - begin])
                                if edge.kind == _FRAME and edge.protocol == MODBUS
                                else None if edge.kind == _DAMAGED else requests[edge.start - begin])

    for s in range(begin, stop):
        here = best[s - begin]
        if here == _NEVER:
            continue
        header = (data[s], data[s + 1]) if s + 1 < stop else (0, 0)
        for end, score, flags, protocol, direction in frames[s - begin]:
            score += ev.direction_bonus(direction, header, requests[s - begin])
            inside = _pauses_in(pauses, s, end) * ev.PAUSE_INSIDE if pauses else 0.0
            offer(_Edge(s, end, _FRAME, flags, protocol), here + score + inside + supported(s) + supported(end))
            frame_ends.add(end)
        glitch = (
            (back[s - begin] is not None and back[s - begin].kind == _FRAME)  # type: ignore[union-attr]
            or (s == begin and start_after_frame)
            or (s + 1 < stop and bool(frames[s + 1 - begin]))
            or (s + 1 == stop and end_before_frame)
        )
        offer(_Edge(s, s + 1, _NOISE), here + (ev.GLITCH_BYTE if glitch else ev.NOISE_BYTE))
        starts_supported = (s == begin and (start_after_frame or begin == 0)) or s in pause_set or s in frame_ends
        # Where a valid frame starts, no damaged one does: its bytes pass the CRC.
        if starts_supported and not frames[s - begin]:
            for edge, score in _damaged_at(data, s, stop, frame_starts, pauses, closed_at_stop,
                                           context, requests[s - begin]):
                offer(edge, here + score)
    if open_end:
        return _commit_agreed(data, begin, stop, back, requests, context)
    return _Parse(_pieces(data, begin, _traceback(back, begin, stop), context), stop, requests[size])


def _valid_at(data: bytes, s: int, stop: int, begin: int, context: Context, pause_set: set[int]) -> list[ev.Reading]:
    supported = s == begin or s in pause_set
    found = ev.valid_frames_at(data, s, stop, search_unknown=supported)
    if context.timed and s == 0 and stop == len(data) and context.closed and ev.whole_run_frame(data, 0, stop):
        if not any(end == stop for end, *_ in found):
            found.append((stop, ev.CRC_MATCH + ev.LENGTH_SEARCHED, FrameFlag.BAD_LENGTH, MODBUS, ev.NO_DIRECTION))
    return found


def _damaged_at(
    data: bytes, s: int, stop: int, frame_starts: list[int], pauses: tuple[int, ...], closed_at_stop: bool,
    context: Context, open_request: OpenRequest,
) -> list[tuple[_Edge, float]]:
    """Damaged frames from ``s`` to a supported boundary: the next valid frame (or the
    byte before it, a glitch), a pause, or the segment's end."""
    if stop - s < ev.MIN_ADU or not ev.plausible_damaged_header(data[s], data[s + 1]):
        return []
    limit = min(stop, s + MAX_ADU)
    following = bisect_right(frame_starts, s)
    next_frame = frame_starts[following] if following < len(frame_starts) else None
    if next_frame is not None:
        limit = min(limit, next_frame)
    ends = {p for p in pauses[bisect_right(pauses, s):bisect_right(pauses, limit)]}
    if next_frame is not None and next_frame <= s + MAX_ADU:
        ends |= {next_frame, next_frame - 1}
    if closed_at_stop and stop <= s + MAX_ADU and (next_frame is None or next_frame >= stop):
        ends.add(stop)
    edges = []
    at_end = context.at_capture_end and context.closed
    for end in sorted(e for e in ends if e - s >= ev.MIN_ADU):
        flags, fits = ev.damaged_flags(data[s:end], open_request=open_request, at_capture_end=at_end and end == stop)
        score = ev.DAMAGED + (ev.DAMAGED_FITS_RULE if fits else 0.0) + _pauses_in(pauses, s, end) * ev.PAUSE_INSIDE
        edges.append((_Edge(s, end, _DAMAGED, flags), score))
    return edges


def _traceback(back: list[_Edge | None], begin: int, position: int) -> list[_Edge]:
    edges = []
    while position > begin:
        edge = back[position - begin]
        assert edge is not None  # every position is reachable by noise bytes
        edges.append(edge)
        position = edge.start
    edges.reverse()
    return edges


def _commit_agreed(
    data: bytes, begin: int, stop: int, back: list[_Edge | None], requests: list[OpenRequest], context: Context
) -> _Parse:
    """Pieces on the best path to every position a longer parse can continue from."""
    frontier = set(range(max(begin + 1, stop - MAX_EDGE), stop + 1))
    while len(frontier) > 1:
        latest = max(frontier)
        frontier.discard(latest)
        edge = back[latest - begin]
        assert edge is not None
        frontier.add(edge.start)
    (agreed,) = frontier
    return _Parse(_pieces(data, begin, _traceback(back, begin, agreed), context), agreed,
                        requests[agreed - begin])


def _pieces(data: bytes, begin: int, edges: list[_Edge], context: Context) -> list[Piece]:
    """Edges as pieces: noise bytes joined into runs (split at pauses), damaged frames at
    the very start of a capture (its first bytes are the tail of a frame) taken as noise."""
    pause_set = set(context.pauses)
    pieces: list[Piece] = []
    for edge in edges:
        if edge.kind == _NOISE or (edge.kind == _DAMAGED and edge.start == 0 and context.at_capture_start):
            last = pieces[-1] if pieces else None
            if last is not None and last.is_noise and last.end == edge.start and edge.start not in pause_set:
                pieces[-1] = Piece(last.start, edge.end, is_noise=True, crc_ok=False)
            else:
                pieces.append(Piece(edge.start, edge.end, is_noise=True, crc_ok=False))
        else:
            pieces.append(Piece(edge.start, edge.end, crc_ok=edge.kind == _FRAME, flags=edge.flags,
                                protocol=edge.protocol))
    return pieces
