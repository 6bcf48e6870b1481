"""Splitting a run of bytes into frames by their content: length rules and CRC.

A *segment* is a run of bytes that timing could not split further (no silence of
t3.5 on an exact capture; no gap far above the delivery jitter on a host one). It
may hold one frame, several (a slave that answers too fast, a host read holding
many frames), stray bytes, or a damaged frame. :func:`parse_segment` cuts it into
:class:`Piece` s, each a frame or noise, covering every byte exactly once.

The rules, in order of trust:

1. Timing and CRC agree: a closed segment whose bytes, as a whole, pass the CRC
   and fit their function code's length rule is one frame.
2. A frame starts at a position when its function code's length rule, read from
   the bytes there, gives a length whose CRC holds. Unknown function codes (no
   length rule) are found by CRC search up to 256 bytes.
3. False CRC matches (1 in 65536 per try) are guarded against where they are most
   likely, while resynchronising through bytes that form no frame and in CRC
   search: such a candidate is taken only if it ends where timing ends the segment
   or is followed by a frame found by rule 2; a CRC-search candidate must moreover
   not overlap a frame that rule 2 finds starting inside it (stray bytes before a
   frame can pass the CRC together with the frame's first bytes).
4. Bytes where no frame starts: if their header (address, function code) gives a
   length that ends at the segment's end or just before a valid frame, they are
   one damaged frame (``crc_ok`` false); other runs are classified by
   :func:`classify_leftover`.
"""

from __future__ import annotations

from dataclasses import dataclass

from decoders.crc import crc_ok
from decoders.frame import MODBUS, USS, FrameFlag
from decoders.modbus.codes import EXCEPTION_BIT, FUNCTION_NAMES, USER_DEFINED_FUNCTIONS
from decoders.modbus.layouts import LAYOUTS, MAX_ADU, exception_length
from decoders.uss import uss_length

MIN_ADU = 4
MAX_ADDRESS = 247
USS_STX = 0x02
BROADCAST_ADDRESS = 0

#: (slave, function) of the request that awaits its response, if any.
OpenRequest = tuple[int, int] | None


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes ``[start, end)`` of a segment: a frame, or noise."""

    start: int
    end: int
    is_noise: bool = False
    crc_ok: bool = True
    flags: FrameFlag = FrameFlag.NONE
    protocol: int = MODBUS


def rule_lengths(adu: bytes) -> list[int | None]:
    """The lengths the length rules give for ``adu``'s function code, request first.

    ``None`` stands for a direction whose length is not yet known from these bytes;
    an empty list means the function code has no length rule.
    """
    if len(adu) < 2:
        return []
    function = adu[1]
    if function & EXCEPTION_BIT:
        return [exception_length(adu)] if (function & ~EXCEPTION_BIT) in LAYOUTS else []
    layout = LAYOUTS.get(function)
    if layout is None:
        return []
    request, response = layout.request(adu), layout.response(adu)
    return [request] if request == response else [request, response]


def plausible_header(adu: bytes) -> bool:
    """An address a slave can have (or broadcast) and a function code that exists."""
    if len(adu) < 2 or adu[0] > MAX_ADDRESS:
        return False
    function = adu[1] & ~EXCEPTION_BIT
    return function in FUNCTION_NAMES or function in USER_DEFINED_FUNCTIONS


def fits_rules(adu: bytes) -> bool:
    """Whether ``adu``'s length is one its length rules allow."""
    return len(adu) in rule_lengths(adu)


def _searchable(adu: bytes) -> bool:
    """Function codes whose length only CRC search can find."""
    if adu[0] > MAX_ADDRESS or adu[1] == 0:
        return False
    return not any(length is not None for length in rule_lengths(adu))


def expected_lengths(head: bytes, open_request: OpenRequest) -> list[int]:
    """Rule lengths in the order to try them: the expected direction first (a
    response to the open request, else a request), then the shorter one."""
    lengths = rule_lengths(head)
    if len(lengths) == 2 and open_request == (head[0], head[1]):
        lengths.reverse()
    return [n for n in lengths if n is not None]


def frame_at(
    data: bytes, pos: int, end: int, *, confirm: bool, closed: bool, open_request: OpenRequest = None
) -> int | None:
    """Length of a CRC-valid frame starting at ``pos`` (within ``end``), or ``None``.

    With ``confirm``, a candidate must also end at a closed segment's end or be
    followed by a frame found by length rule (rule 3 of the module docstring).
    """
    if end - pos < MIN_ADU or data[pos] > MAX_ADDRESS:
        return None
    head = data[pos : min(end, pos + MAX_ADU)]
    for length in expected_lengths(head, open_request):
        if (
            MIN_ADU <= length <= len(head)
            and crc_ok(head[:length])
            and (not confirm or _confirmed(data, pos + length, end, closed))
        ):
            return length
    if _searchable(head):
        for length in range(MIN_ADU, len(head) + 1):
            if (
                crc_ok(head[:length])
                and _confirmed(data, pos + length, end, closed)
                and not _rule_frame_starts_inside(data, pos, pos + length, end)
            ):
                return length
    return None


def _rule_frame_starts_inside(data: bytes, start: int, stop: int, end: int) -> bool:
    """Whether a frame found by its length rule (within ``end``) starts strictly inside ``[start, stop)``."""
    for q in range(start + 1, min(stop, end - MIN_ADU + 1)):
        head = data[q : min(end, q + MAX_ADU)]
        if head[0] <= MAX_ADDRESS and any(
            n is not None and MIN_ADU <= n <= len(head) and crc_ok(head[:n]) for n in rule_lengths(head)
        ):
            return True
    return False


def uss_at(data: bytes, pos: int, end: int, *, confirm: bool, closed: bool) -> int | None:
    """Length of a USS telegram starting at ``pos``, confirmed like a resync candidate."""
    length = uss_length(data[pos : min(end, pos + MAX_ADU)])
    if length is None or (confirm and not _confirmed(data, pos + length, end, closed)):
        return None
    return length


def _confirmed(data: bytes, after: int, end: int, closed: bool, *, by_damaged: bool = True) -> bool:
    """Whether a frame may end at ``after``: the segment ends there (timing), or a valid
    frame or USS telegram follows, or (``by_damaged``) a damaged frame whose own end is confirmed."""
    if after == end:
        return closed
    if frame_at(data, after, end, confirm=False, closed=closed) is not None:
        return True
    if uss_length(data[after : min(end, after + MAX_ADU)]) is not None:
        return True
    return by_damaged and _damaged_frame_length(data, after, end, closed=closed, at_capture_end=False) is not None


def classify_leftover(adu: bytes, *, at_capture_start: bool) -> Piece:
    """Bytes in which no valid frame was found: a damaged frame, or noise.

    A capture that starts mid-frame starts with noise; so do runs too short for a
    frame or without a plausible header. Otherwise the bytes are one frame with a
    bad CRC, ``truncated`` if its length rule wants more, ``bad_length`` if less.
    """
    if at_capture_start or not MIN_ADU <= len(adu) <= MAX_ADU or not plausible_header(adu):
        return Piece(0, len(adu), is_noise=True, crc_ok=False)
    lengths = rule_lengths(adu)
    flags = FrameFlag.NONE
    if lengths and len(adu) not in lengths:
        longer = any(length is None or length > len(adu) for length in lengths)
        flags = FrameFlag.TRUNCATED if longer else FrameFlag.BAD_LENGTH
    return Piece(0, len(adu), crc_ok=False, flags=flags)


def _damaged_frame_length(
    data: bytes, pos: int, end: int, *, closed: bool, at_capture_end: bool, open_request: OpenRequest = None
) -> int | None:
    """A header whose rule length ends where timing or the next valid frame says, or
    leaves only a few stray bytes (too few for a frame) before a closed segment's end.

    A damaged frame is weaker evidence than a valid one: the hypothesis is dropped
    when a valid frame starts inside it (stray bytes before a frame), and at the end
    of the capture when a longer rule length says the frame was cut off.
    """
    head = data[pos : min(end, pos + MAX_ADU)]
    if len(head) < MIN_ADU or not plausible_header(head):
        return None
    if at_capture_end and any(n is None or n > len(head) for n in rule_lengths(head)):
        return None
    for length in expected_lengths(head, open_request):
        if not MIN_ADU <= length <= len(head):
            continue
        after = pos + length
        if not (_confirmed(data, after, end, closed, by_damaged=False) or (closed and end - after < MIN_ADU)):
            continue
        if any(frame_at(data, q, end, confirm=True, closed=closed) for q in range(pos + 1, after)):
            return None
        return length
    return None


@dataclass(slots=True)
class SegmentParse:
    """Pieces of a segment; ``consumed`` is how far they reach (all of it when closed);
    ``open_request`` is the request still awaiting its response after them."""

    pieces: list[Piece]
    consumed: int
    open_request: OpenRequest = None


def after_frame(frame: bytes, open_request: OpenRequest) -> OpenRequest:
    """The open request once ``frame`` (CRC-valid) has passed on the wire."""
    slave, function = frame[0], frame[1]
    if function & EXCEPTION_BIT:
        return None
    lengths = rule_lengths(frame)
    answers = open_request == (slave, function) and len(frame) == (lengths[-1] if lengths else -1)
    if answers or slave == BROADCAST_ADDRESS or not lengths or len(frame) != lengths[0]:
        return None
    return (slave, function)


#: An open segment is parsed only up to this many bytes before its current end, so
#: that a frame starting there and the frame confirming it are both complete.
OPEN_LOOKAHEAD = 2 * MAX_ADU


def parse_segment(
    data: bytes,
    *,
    closed: bool,
    at_capture_start: bool,
    at_capture_end: bool = False,
    open_request: OpenRequest = None,
) -> SegmentParse:
    """Cut ``data`` into pieces.

    ``closed``: timing (or the end of the capture) ends the segment here, and every
    byte is placed. Of an open segment, only what lies ``OPEN_LOOKAHEAD`` bytes
    before its end is placed; ``consumed`` says where the rest begins.
    """
    end = len(data)
    context = _Context(data, end, closed, at_capture_start, at_capture_end, open_request)
    if closed:
        whole_crc_ok = end <= MAX_ADU and crc_ok(data) and not _zero_padded_frame(data, open_request)
        if whole_crc_ok and (fits_rules(data) or not rule_lengths(data)):
            return SegmentParse([Piece(0, end)], end, after_frame(data, open_request))
        parse = _sequential(context, end)
        if whole_crc_ok and not any(p.crc_ok and not p.is_noise for p in parse.pieces):
            # Timing and CRC agree on one frame; its length fits no rule.
            return SegmentParse([Piece(0, end, flags=FrameFlag.BAD_LENGTH)], end)
        return parse
    return _sequential(context, end - OPEN_LOOKAHEAD)


def _zero_padded_frame(data: bytes, open_request: OpenRequest) -> bool:
    """A valid frame followed only by 0x00 bytes.

    Zero bytes after a Modbus frame leave the CRC register at 0, so such a run passes
    the CRC as a whole whatever its length: the whole-run CRC is no evidence there,
    and the frame that the length rule finds at the start is the better reading.
    """
    length = frame_at(data, 0, len(data), confirm=False, closed=False, open_request=open_request)
    return length is not None and length < len(data) and not any(data[length:])


@dataclass(frozen=True, slots=True)
class _Context:
    data: bytes
    end: int
    closed: bool
    at_start: bool
    at_end: bool
    open_request: OpenRequest


def _sequential(ctx: _Context, limit: int) -> SegmentParse:
    """Frames found left to right up to ``limit``; runs between them become leftovers."""
    data, end, closed = ctx.data, ctx.end, ctx.closed
    pieces: list[Piece] = []
    pos = 0
    unmatched: int | None = None
    open_request = ctx.open_request
    while pos < limit:
        length = frame_at(data, pos, end, confirm=unmatched is not None, closed=closed, open_request=open_request)
        damaged = False
        if length is None and data[pos] == USS_STX:
            uss = uss_at(data, pos, end, confirm=unmatched is not None, closed=closed)
            if uss is not None:
                if unmatched is not None:
                    pieces.append(_leftover(data, unmatched, pos, ctx.at_start and not pieces))
                    unmatched = None
                pieces.append(Piece(pos, pos + uss, protocol=USS))
                pos += uss
                continue
        if length is None and unmatched is None:
            length = _damaged_frame_length(
                data, pos, end, closed=closed, at_capture_end=ctx.at_end, open_request=open_request
            )
            damaged = length is not None
        if length is None:
            unmatched = pos if unmatched is None else unmatched
            pos += 1
            continue
        if unmatched is not None:
            pieces.append(_leftover(data, unmatched, pos, ctx.at_start and not pieces))
            unmatched = None
        noise = damaged and ctx.at_start and not pieces
        pieces.append(Piece(pos, pos + length, is_noise=noise, crc_ok=not damaged))
        open_request = None if damaged else after_frame(data[pos : pos + length], open_request)
        pos += length
    if unmatched is None:
        return SegmentParse(pieces, pos, open_request)
    if closed:
        pieces.append(_leftover(data, unmatched, end, ctx.at_start and not pieces))
        return SegmentParse(pieces, end, None)
    if limit - unmatched >= MAX_ADU:
        # No frame starts anywhere in this run: it is noise, and need not wait.
        pieces.append(_leftover(data, unmatched, limit, ctx.at_start and not pieces))
        return SegmentParse(pieces, limit, None)
    return SegmentParse(pieces, unmatched, open_request)


def _leftover(data: bytes, start: int, end: int, at_capture_start: bool) -> Piece:
    piece = classify_leftover(data[start:end], at_capture_start=at_capture_start)
    return Piece(start, end, piece.is_noise, piece.crc_ok, piece.flags)

