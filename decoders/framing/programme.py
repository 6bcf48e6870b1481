"""The dynamic programme of the best parse: the highest-scoring pieces over a run of bytes.

Positions are visited left to right; from each reachable position every candidate
piece (a CRC-valid reading, a damaged frame, one noise byte) offers its end the
score so far plus its own (:mod:`decoders.framing.evidence`); each position keeps
the best offer and where it came from (Viterbi). The open request along the best
path to a position decides the expected direction of readings starting there.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from dataclasses import dataclass, field

from decoders.frame import MODBUS, FrameFlag
from decoders.framing import evidence as ev
from decoders.framing.content import MIN_ADU, OpenRequest, after_frame, awaits
from decoders.modbus.layouts import MAX_ADU

#: The longest piece the programme can take, with a stray byte on either side.
MAX_EDGE = MAX_ADU + 2


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes ``[start, end)`` of a segment: a frame, or noise."""

    start: int
    end: int
    is_noise: bool = False
    crc_ok: bool = True
    flags: FrameFlag = FrameFlag.NONE
    protocol: int = MODBUS


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
    #: Positions (relative to the segment) of characters the receiver saw with a framing error.
    framing_errors: tuple[int, ...] = ()
    #: A valid frame ends where these bytes begin: they are the rest of an open segment whose
    #: first frames were committed already (see :mod:`decoders.framing.best_parse`, streaming).
    follows_frame: bool = False


@dataclass(frozen=True, slots=True)
class Region:
    """``data[begin:stop]``, the bytes one programme runs over, and what lies around them."""

    data: bytes
    begin: int
    stop: int
    context: Context
    search: ev.CrcSearch
    #: A frame ends where the region begins (its first byte may be that frame's glitch).
    after_frame: bool = False
    #: A frame starts where the region stops.
    before_frame: bool = False
    #: More bytes may follow ``stop`` (only what every best path agrees on is kept).
    open_end: bool = False
    pause_set: frozenset[int] = field(init=False)
    framing_error_set: frozenset[int] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "pause_set", frozenset(self.context.pauses))
        object.__setattr__(self, "framing_error_set", frozenset(self.context.framing_errors))

    @property
    def closed_at_stop(self) -> bool:
        """Whether nothing continues past ``stop`` (a segment end, or an anchor)."""
        return not self.open_end and (self.stop < len(self.data) or self.context.closed)


@dataclass(slots=True)
class Parse:
    """Pieces of a region, how far they reach, and the open request after them."""

    pieces: list[Piece]
    consumed: int
    open_request: OpenRequest


@dataclass(slots=True)
class _Edge:
    start: int
    end: int
    kind: int  # _FRAME, _DAMAGED or _NOISE
    flags: FrameFlag = FrameFlag.NONE
    protocol: int = MODBUS


_FRAME, _DAMAGED, _NOISE = 0, 1, 2
_NEVER = float("-inf")


def pauses_in(pauses: tuple[int, ...], start: int, stop: int) -> int:
    """How many pauses lie strictly inside ``[start, stop)``."""
    return bisect_left(pauses, stop) - bisect_right(pauses, start)


class _Programme:
    """One run of the programme over a region."""

    def __init__(self, region: Region, open_request: OpenRequest) -> None:
        self.region = region
        begin, stop = region.begin, region.stop
        #: Ends of the readings found so far (left to right) by a length rule: a frame may end
        #: there, so a length found by CRC search may start there (as after an anchor).
        self._rule_ends: set[int] = set()
        #: Whether a reading the programme over the whole segment keeps ends past the region's
        #: stop, where an anchor starts: then that anchor is no anchor (see
        #: :mod:`decoders.framing.crossing`, rule 1).
        self.crossed = False
        self.readings = []
        for s in range(begin, stop):
            found = self._readings_at(s)
            self._rule_ends.update(end for end, *_, direction in found if direction != ev.SEARCHED)
            self.readings.append(found)
        self.starts_of_frames = self._searched_where_supported()
        self.frame_starts = sorted(self.starts_of_frames)
        size = stop - begin
        self.best = [_NEVER] * (size + 1)
        self.back: list[_Edge | None] = [None] * (size + 1)
        self.requests: list[OpenRequest] = [None] * (size + 1)
        self.best[0], self.requests[0] = 0.0, open_request
        self.frame_ends = {begin} if region.after_frame else set()

    def run(self) -> Parse:
        region = self.region
        for s in range(region.begin, region.stop):
            if self.best[s - region.begin] != _NEVER:
                self._visit(s)
        if region.open_end:
            return self._commit_agreed()
        return Parse(self._pieces(self._traceback(region.stop)), region.stop, self.requests[-1])

    def _readings_at(self, s: int) -> list[ev.Reading]:
        region = self.region
        data, stop, context = region.data, region.stop, region.context
        supported = s == region.begin or s in region.pause_set or s in self._rule_ends
        # Before an anchor, every reading the whole segment holds, as the programme over it reads
        # them (a length rule's count may lie past the region); those past the anchor's start
        # are its business (``crossed``).
        reach = len(data) if region.before_frame else stop
        found = ev.valid_frames_at(data, s, reach, search_unknown=supported, search=region.search)
        if found and reach > stop and any(reading[0] > stop for reading in found):
            self.crossed = self.crossed or any(reading[0] > stop and self._kept_past(reading) for reading in found)
            found = [reading for reading in found if reading[0] <= stop]
        whole = context.timed and context.closed and s == 0 and stop == len(data)
        if whole and ev.whole_run_frame(data, 0, stop) and not any(reading[0] == stop for reading in found):
            found.append((stop, ev.CRC_MATCH + ev.LENGTH_SEARCHED, FrameFlag.BAD_LENGTH, MODBUS, ev.NO_DIRECTION))
        return found

    def _kept_past(self, reading: ev.Reading) -> bool:
        """Whether the programme over the whole segment keeps ``reading``, which ends past the
        region: by rule, or by CRC search where a boundary may support its end (the segment's
        end, a pause, the start of any reading there)."""
        end, *_, direction = reading
        region = self.region
        data, context = region.data, region.context
        if direction != ev.SEARCHED or (end == len(data) and context.closed) or end in region.pause_set:
            return True
        return bool(ev.valid_frames_at(data, end, len(data), search_unknown=True, search=region.search))

    def _searched_where_supported(self) -> set[int]:
        """Drops the lengths found by CRC search whose end no boundary supports (the region's
        closed end, a pause, another reading's start; near the end of a region more bytes may
        follow, where such a reading may yet end): no evidence, they are no frame start either (a
        damaged frame may start there). Right to left, as a searched length may end where
        another one, supported, starts. The starts of the readings left."""
        region = self.region
        begin = region.begin
        starts: set[int] = set()
        at = [s for s in range(region.stop - 1, begin - 1, -1) if self.readings[s - begin]]  # most hold none
        for s in at:
            found = self.readings[s - begin]
            if any(direction == ev.SEARCHED for *_, direction in found):
                found = self.readings[s - begin] = [reading for reading in found if reading[4] != ev.SEARCHED
                                                    or self._search_end_supported(reading[0], starts)]
            if found:
                starts.add(s)
        return starts

    def _supported(self, position: int) -> float:
        """The evidence of a boundary at ``position``: a pause, or the segment's end (an anchor
        after the region is none: the programme over the whole segment sees none there)."""
        region = self.region
        if position in region.pause_set or (position == len(region.data) and region.closed_at_stop):
            return ev.BOUNDARY_SUPPORTED
        return 0.0

    def _offer(self, edge: _Edge, score: float) -> None:
        begin, data = self.region.begin, self.region.data
        target = edge.end - begin
        if score > self.best[target]:
            self.best[target], self.back[target] = score, edge
            before = self.requests[edge.start - begin]
            if edge.kind == _FRAME and edge.protocol == MODBUS:
                self.requests[target] = after_frame(data[edge.start : edge.end], before)
            else:
                self.requests[target] = None if edge.kind == _DAMAGED else before

    def _visit(self, s: int) -> None:
        region = self.region
        begin, stop, data = region.begin, region.stop, region.data
        here = self.best[s - begin]
        open_request = self.requests[s - begin]
        starts_supported = (
            (s == begin and (region.after_frame or begin == 0)) or s in region.pause_set or s in self.frame_ends
            or s - 1 in region.framing_error_set
        )
        pauses = region.context.pauses
        for end, score, flags, protocol, direction in self.readings[s - begin]:
            if direction == ev.SEARCHED and not starts_supported:
                continue  # a length found by CRC search counts only between supported boundaries
            total = score + ev.direction_bonus(direction, data[s:end], open_request) + self._supported(s)
            total += self._supported(end) + (pauses_in(pauses, s, end) * ev.PAUSE_INSIDE if pauses else 0.0)
            self._offer(_Edge(s, end, _FRAME, flags, protocol), here + total)
            self.frame_ends.add(end)
        previous = self.back[s - begin]
        # A glitch sits directly against its transmitter's frame (valid or damaged): no pause between.
        after = (previous is not None and previous.kind != _NOISE) or (s == begin and region.after_frame)
        before = (s + 1 < stop and bool(self.readings[s + 1 - begin])) or (s + 1 == stop and region.before_frame)
        glitch = (after and s not in region.pause_set) or (before and s + 1 not in region.pause_set)
        noise = ev.GLITCH_BYTE if glitch else ev.NOISE_BYTE
        if s in region.framing_error_set:
            noise += ev.FRAMING_ERROR_NOISE
        self._offer(_Edge(s, s + 1, _NOISE), here + noise)
        # Where a valid frame starts, no damaged one does: its bytes pass the CRC.
        if starts_supported and not self.readings[s - begin]:
            for edge, score in self._damaged_at(s, open_request):
                self._offer(edge, here + score)

    def _search_end_supported(self, end: int, starts: set[int]) -> bool:
        region = self.region
        if region.open_end and end > region.stop - MAX_ADU:
            return True  # a reading may start there that ends in bytes still to come
        return (end == region.stop and region.closed_at_stop) or end in region.pause_set or end in starts

    def _damaged_at(self, s: int, open_request: OpenRequest) -> list[tuple[_Edge, float]]:
        """Damaged frames from ``s`` to a supported boundary -- the next valid frame, a pause,
        or the segment's end -- or to the byte before it (a glitch)."""
        region = self.region
        data, stop, pauses = region.data, region.stop, region.context.pauses
        if stop - s < MIN_ADU or not ev.plausible_damaged_header(data[s], data[s + 1]):
            return []
        following = bisect_right(self.frame_starts, s)
        next_frame = self.frame_starts[following] if following < len(self.frame_starts) else None
        limit = min(stop, s + MAX_ADU, next_frame if next_frame is not None else stop)
        boundaries = set(pauses[bisect_right(pauses, s) : bisect_right(pauses, limit)])
        if next_frame is not None and next_frame <= s + MAX_ADU:
            boundaries.add(next_frame)
        if region.closed_at_stop and stop <= s + MAX_ADU and (next_frame is None or next_frame >= stop):
            boundaries.add(stop)
        # A damaged frame may be followed by its transmitter's glitch before the boundary.
        ends = boundaries | {b - 1 for b in boundaries}
        # Only a frame that runs to the capture's end (its last byte, or a glitch, the last) may
        # have been cut off by it.
        at_capture_end = region.context.at_capture_end and region.context.closed
        edges = []
        header = ev.FRAMING_ERROR_HEADER if s in region.framing_error_set else 0.0
        for end in sorted(e for e in ends if e - s >= MIN_ADU):
            flags, fits = ev.damaged_flags(data[s:end], open_request=open_request,
                                           at_capture_end=at_capture_end and end >= len(data) - 1)
            score = ev.DAMAGED + (ev.DAMAGED_FITS_RULE if fits else 0.0) + pauses_in(pauses, s, end) * ev.PAUSE_INSIDE
            score += header
            if awaits(open_request, data[s], data[s + 1]):
                score += ev.EXPECTED_DIRECTION  # the answer the open request awaits, damaged or cut short
            edges.append((_Edge(s, end, _DAMAGED, flags), score))
        return edges

    def _traceback(self, position: int) -> list[_Edge]:
        begin = self.region.begin
        edges = []
        while position > begin:
            edge = self.back[position - begin]
            assert edge is not None  # every position is reachable by noise bytes
            edges.append(edge)
            position = edge.start
        edges.reverse()
        return edges

    def _commit_agreed(self) -> Parse:
        """Pieces on the best path to every position a longer parse can continue from."""
        begin, stop = self.region.begin, self.region.stop
        frontier = set(range(max(begin + 1, stop - MAX_EDGE), stop + 1))
        while len(frontier) > 1:
            latest = max(frontier)
            frontier.discard(latest)
            edge = self.back[latest - begin]
            assert edge is not None
            frontier.add(edge.start)
        (agreed,) = frontier
        return Parse(self._pieces(self._traceback(agreed)), agreed, self.requests[agreed - begin])

    def _pieces(self, edges: list[_Edge]) -> list[Piece]:
        """Edges as pieces: noise bytes joined into runs (split at pauses), damaged frames at
        the very start of a capture (its first bytes are the tail of a frame) taken as noise."""
        context, pause_set = self.region.context, self.region.pause_set
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


def best_pieces(region: Region, open_request: OpenRequest) -> Parse:
    """The best parse of ``region`` (see the module docstring); of an ``open_end``
    region, only the part every best path to its last positions agrees on."""
    return _Programme(region, open_request).run()


def best_pieces_before_anchor(region: Region, open_request: OpenRequest) -> Parse | None:
    """:func:`best_pieces` of a region before an anchor (``before_frame``), or ``None`` where
    a reading from the region ends past its stop (the anchor is none)."""
    programme = _Programme(region, open_request)
    return None if programme.crossed else programme.run()
