"""Vectorised recognition of segments that are one whole, valid frame (or two pieces).

On a healthy exact capture nearly every timing segment is exactly one frame: its
CRC holds and its length is what its function code's length rule says. Those are
recognised here for all segments of a batch at once with numpy lookup tables
derived from :data:`decoders.modbus.codecs.LAYOUTS`; only the others go through
the sequential content parser.

A segment whose last byte is 0x00 is always left to the parser's rules: zero bytes
after a frame keep its CRC valid, so only they can tell a frame padded by a glitch from
a frame that ends in 0x00. The clean-frame rule decides most of them, in columns: those
that otherwise pass (:func:`single_frame_segments` marks them) by :func:`clean_whole`, which
also tells which of them only the programme can cut; the others with the pairs
(:func:`frame_pair_segments`); the programme decides the rest.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from fastcrc import crc16

from decoders.capture import Int64Array
from decoders.crc import crc_ok_spans, prefix_registers
from decoders.framing.content import MAX_ADDRESS, MIN_ADU, rule_lengths
from decoders.framing.evidence import CLEAN_RULES, whole_run_frame
from decoders.framing.rule_tables import (
    NO_RULE,
    OWN_RULE,
    PLAIN_EXCEPTION,
    REQUEST_RULES,
    RESPONSE_RULES,
    checked_readings,
    padded_bytes,
)
from decoders.modbus.codes import DIAGNOSTICS, EXCEPTION_BIT
from decoders.modbus.layouts import EXCEPTION_LENGTH, MAX_ADU
from decoders.runs import spread


def single_frame_segments(
    data: bytes, starts: Int64Array, ends: Int64Array, crc_ok: npt.NDArray[np.bool_]
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Which segments ``data[starts[i]:ends[i]]`` are one valid frame that fits its rule; and
    which pass every test of those but end in 0x00 (zero bytes after a frame keep its CRC
    valid, so its rule with the zeros cut may read it too: :func:`clean_whole` decides them)."""
    if len(starts) == 0:
        return np.zeros(0, np.bool_), np.zeros(0, np.bool_)
    padded = padded_bytes(data)
    seg_lengths = ends - starts
    addresses = padded.take(starts)
    raw_functions = padded[1:].take(starts).astype(np.intp)  # no index array made (see frame_shapes)
    functions = raw_functions & ~EXCEPTION_BIT
    is_exception = (raw_functions & EXCEPTION_BIT) != 0
    fits = np.where(
        is_exception,
        PLAIN_EXCEPTION[functions] & (seg_lengths == EXCEPTION_LENGTH),
        REQUEST_RULES.fits(padded, starts, raw_functions, seg_lengths)
        | RESPONSE_RULES.fits(padded, starts, raw_functions, seg_lengths),
    )
    passing = fits & crc_ok & (seg_lengths >= MIN_ADU) & (seg_lengths <= MAX_ADU) & (addresses <= MAX_ADDRESS)
    zero_ended = padded[np.maximum(ends - 1, 0)] == 0
    return passing & ~zero_ended, passing & zero_ended


def has_own_rule(data: bytes, starts: Int64Array) -> npt.NDArray[np.bool_]:
    """Whether the segment at each of ``starts`` has a function code the tables cannot hold (a
    segment of one byte at the end of ``data`` has none). Its bytes are read in place: the
    starts are few, and a padded copy of the batch would cost more than they do."""
    wire = np.frombuffer(data, np.uint8)
    at = starts + 1
    inside = at < len(wire)
    own: npt.NDArray[np.bool_] = OWN_RULE[wire[np.where(inside, at, 0)]] & inside
    return own


def whole_by_own_rule(segment: bytes) -> bool:
    """Whether ``segment`` is one valid frame by a length rule the tables cannot hold
    (FC 43's objects, FC 24's two-byte count): the scalar test of the segments the
    vectorised one left out, under the same conditions."""
    return (MIN_ADU <= len(segment) <= MAX_ADU and segment[0] <= MAX_ADDRESS and segment[-1] != 0
            and len(segment) in rule_lengths(segment) and crc16.modbus(segment) == 0)


def _clean_rule_tables() -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """``CLEAN_RULES`` as arrays [slot, function]: fixed length, byte-count position, base."""
    fixed = np.zeros((2, 256), np.int64)
    position = np.full((2, 256), NO_RULE, np.int64)
    base = np.zeros((2, 256), np.int64)
    for function, rules in enumerate(CLEAN_RULES):
        for slot, (length, at, plus) in enumerate(rules):
            fixed[slot, function] = length
            if not length:
                position[slot, function], base[slot, function] = at, plus
    return fixed, position, base


_CLEAN_FIXED, _CLEAN_POSITION, _CLEAN_BASE = _clean_rule_tables()
_HAS_CLEAN_RULE = (_CLEAN_FIXED[0] > 0) | (_CLEAN_POSITION[0] >= 0)


def clean_frame_ends(data: bytes, limits: Int64Array | None = None, registers: npt.NDArray[np.uint32] | None = None,
                     readings: list[tuple[Int64Array, Int64Array]] | None = None) -> npt.NDArray[np.int64]:
    """For every position of ``data``: the end of the clean frame starting there, or 0
    (what :func:`decoders.framing.best_parse.clean_frame_end` says, for all positions at once).
    ``limits``: per position, where its run of bytes stops (default: the end of ``data``);
    ``registers``: :func:`prefix_registers` of ``data``, where the caller has them;
    ``readings``: gets the starts and ends of the CRC-valid readings by rule found on the way
    (of addresses 1 to 247, :func:`checked_readings` of those, rules the tables hold)."""
    size = len(data)
    ends = np.zeros(size, np.int64)
    if size < MIN_ADU:
        return ends
    padded = padded_bytes(data)
    # Positions whose address is 1..247 and whose function code has a clean rule: ~1 in 7.
    heads = padded[: size - MIN_ADU + 1]
    functions_all = padded[1 : size - MIN_ADU + 2]
    positions = np.flatnonzero((heads - np.uint8(1) < np.uint8(MAX_ADDRESS)) & _HAS_CLEAN_RULE[functions_all])
    functions = functions_all[positions].astype(np.intp)
    if registers is None:
        registers = prefix_registers(data)
    valid_count = np.zeros(size, np.int64)
    limit = size if limits is None else limits[positions]
    for slot in (0, 1):
        fixed, at = _CLEAN_FIXED[slot, functions], _CLEAN_POSITION[slot, functions]
        counted = at >= 0
        lengths = np.where(counted, _CLEAN_BASE[slot, functions] + padded[positions + np.maximum(at, 0)], fixed)
        usable = ((fixed > 0) | (counted & (positions + at < limit))) & (positions + lengths <= limit)
        starts = positions[usable]
        good = crc_ok_spans(registers, starts, lengths[usable])
        stops = starts + lengths[usable]
        good_starts, good_stops = starts[good], stops[good]
        if readings is not None:
            readings.append((good_starts, good_stops))
        # Two rules giving one length are one reading, not two.
        valid_count[good_starts] += ends[good_starts] != good_stops
        ends[good_starts] = good_stops
    ends[valid_count > 1] = 0  # both directions pass: the programme decides
    ends[_echoes_read_otherwise(padded, registers, ends, limits)] = 0
    return ends


def clean_whole(
    data: bytes, starts: Int64Array, ends: Int64Array
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Of segments ``data[starts[i]:ends[i]]`` that fit their rule and pass the CRC: whether
    each is one clean frame, as :func:`~decoders.framing.best_parse.clean_frame_end` of its
    start within its end says, in columns; and which ones that answer settles. For the few
    segments of a batch that would be whole frames but end in 0x00 (about 100 of 25 000 polling
    frames): their rule with the zeros cut reads them too where it is another rule's length,
    and the CRC of that shorter reading decides.

    FC 8 echoes (return query data, any length) are not settled: :func:`frame_pair_segments`
    weighs them. Of the settled ones, those not whole are no pair nor a frame and stray bytes
    either (the clean frame at their start, if any, is the whole segment): only the programme
    can cut them."""
    # Read in place, as has_own_rule reads: the segments are few, a padded copy of the batch
    # would cost more. A segment that fits a rule has its first MIN_ADU bytes.
    wire = np.frombuffer(data, np.uint8)
    lengths = ends - starts
    functions = wire[starts + 1].astype(np.intp)
    settled = ~((functions == DIAGNOSTICS) & (wire[starts + 2] == 0) & (wire[starts + 3] == 0))
    whole = ((wire[starts] - np.uint8(1)) < np.uint8(MAX_ADDRESS)) & (lengths >= MIN_ADU) & settled
    reaches_end = np.zeros(len(starts), np.bool_)
    for slot in (0, 1):
        at = _CLEAN_POSITION[slot, functions]
        # A count past the segment's end (read at its last byte instead) gives a length past it.
        count = wire[np.minimum(starts + np.maximum(at, 0), ends - 1)]
        rule = np.where(at >= 0, _CLEAN_BASE[slot, functions] + count, _CLEAN_FIXED[slot, functions])
        # No rule: 0.
        usable = (rule > 0) & (rule <= lengths)
        reaches_end |= usable & (rule == lengths)
        shorter = np.flatnonzero(usable & (rule < lengths) & whole)
        if len(shorter):  # two readings where the shorter one passes the CRC too
            spans = zip(starts[shorter].tolist(), (starts + rule)[shorter].tolist(), strict=True)
            whole[shorter] = [crc16.modbus(data[begin:stop]) != 0 for begin, stop in spans]
    return whole & reaches_end, settled


#: Echoes tested at once for another CRC-valid length (bounds the [echo, length] matrix).
_ECHO_BLOCK = 4096


def _echoes_read_otherwise(
    padded: npt.NDArray[np.uint8], registers: npt.NDArray[np.uint32], ends: npt.NDArray[np.int64],
    limits: Int64Array | None,
) -> Int64Array:
    """Clean-by-rule FC 8 sub-function 0 frames (return query data: an echo of any length,
    so CRC search reads it too) with another CRC-valid length from the same start: two
    readings, for the programme to weigh (:func:`decoders.framing.evidence.any_length_echo`, in columns)."""
    size = len(ends)
    candidates = np.flatnonzero(ends)
    candidates = candidates[(padded[candidates + 1] == DIAGNOSTICS) & (padded[candidates + 2] == 0)
                            & (padded[candidates + 3] == 0)]
    lengths = np.arange(MIN_ADU, MAX_ADU + 1, dtype=np.int64)
    read_otherwise = []
    for block in range(0, len(candidates), _ECHO_BLOCK):
        starts = candidates[block : block + _ECHO_BLOCK]
        limit = size if limits is None else limits[starts]
        stops = starts[:, None] + lengths[None, :]
        usable = (stops <= np.reshape(limit, (-1, 1))) & (stops != ends[starts][:, None])
        spans = np.broadcast_to(starts[:, None], stops.shape)[usable]
        other = np.zeros(stops.shape, np.bool_)
        other[usable] = crc_ok_spans(registers, spans, (stops - starts[:, None])[usable])
        read_otherwise.append(starts[other.any(axis=1)])
    return np.concatenate(read_otherwise) if read_otherwise else np.zeros(0, np.int64)


#: Stray bytes after a frame that are noise whatever they hold: no reading is this short.
MAX_STRAY = MIN_ADU - 1


def frame_pair_segments(
    data: bytes, seg_starts: Int64Array, seg_ends: Int64Array, pause_at: npt.NDArray[np.bool_] | None,
    error_at: npt.NDArray[np.bool_] | None = None,
) -> tuple[Int64Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Of segments the vectorised single-frame test left out: where each one's first piece
    ends, for those that are a clean frame followed by another clean frame (a fast answer) or
    by 1..3 stray bytes (a glitch), else 0; whether the rest is that second frame; and whether
    the segment is one clean frame after all (:func:`~decoders.framing.best_parse.clean_frame_end`
    over the whole segment: one ending in 0x00 whose prefix fits no rule).

    The parse of such a segment is known without the programme: its frames are anchors of
    :mod:`decoders.framing.best_parse` (clean, no other clean frame starting inside, no
    pause inside, touching the segment's start or each other), and fewer than ``MIN_ADU``
    bytes hold no reading, so they are noise; but not where a reading crosses from the frame
    into the stray bytes, or a frame may start inside the frame (the rules of
    :mod:`decoders.framing.crossing`, 2 and 3): the programme weighs those. ``pause_at[q]``:
    byte ``q`` of ``data`` follows a silence > t1.5 (``None``: no pauses, host timing);
    ``error_at[q]``: the receiver saw byte ``q`` with a framing error (``None``: none).
    """
    count = len(seg_starts)
    lengths = seg_ends - seg_starts
    offsets = np.zeros(count + 1, np.int64)
    np.cumsum(lengths, out=offsets[1:])
    total = int(offsets[-1])
    bounds = zip(seg_starts.tolist(), seg_ends.tolist(), strict=True)
    joined = b"".join([data[begin:stop] for begin, stop in bounds])
    registers = prefix_registers(joined)
    ends = clean_frame_ends(joined, np.repeat(offsets[1:], lengths), registers)
    clean_before = np.zeros(total + 1, np.int64)  # [q]: clean frames starting before q
    np.cumsum(ends > 0, out=clean_before[1:])
    pauses_before = np.zeros(total + 1, np.int64)
    # Where each joined byte lies in ``data``: needed only to read the pauses or the errors.
    at_data = None if pause_at is None and error_at is None else spread(seg_starts, lengths)
    if pause_at is not None:
        np.cumsum(pause_at[at_data], out=pauses_before[1:])
    begin, stop = offsets[:-1], offsets[1:]
    first_end = ends[begin]  # segments are never empty: every begin is a position
    split = np.where((first_end > begin) & (first_end < stop), first_end, begin + 1)

    def quiet(start: Int64Array, end: Int64Array) -> npt.NDArray[np.bool_]:
        """No clean frame starts and no pause lies strictly inside ``(start, end)``."""
        after = np.minimum(start + 1, total)
        inside = np.maximum(after, end)
        none: npt.NDArray[np.bool_] = (clean_before[inside] == clean_before[after]) & (
            pauses_before[inside] == pauses_before[after])
        return none

    first_ok = (first_end > begin) & (first_end < stop) & quiet(begin, split)
    second_frame = ends[np.minimum(split, max(total - 1, 0))] == stop
    second_ok = second_frame & quiet(split, stop)
    stray_ok = (stop - split <= MAX_STRAY) & quiet(split, stop)
    known = first_ok & (second_ok | stray_ok)
    stray = np.flatnonzero(known & ~second_ok)
    if len(stray):
        errors = None if error_at is None or at_data is None else np.flatnonzero(error_at[at_data])
        known[stray[_reached_into_strays(joined, registers, (begin[stray], split[stray], stop[stray]), errors)]] = False
    first_length = np.where(known, split - begin, 0)
    return first_length, known & second_ok, first_end == stop


def _reached_into_strays(data: bytes, registers: npt.NDArray[np.uint32],
                         segments: tuple[Int64Array, Int64Array, Int64Array],
                         errors: Int64Array | None) -> npt.NDArray[np.bool_]:
    """Of segments of a frame ``[begin, split)`` and stray bytes ``[split, stop)``: those where
    a reading from inside the frame ends among the stray bytes, or a frame may start inside the
    frame (a reading ends there, or a character with a framing error comes just before: at
    ``errors``, sorted), or the whole segment passes the CRC (a frame of a bad length, where
    timing closes it)."""
    begin, split, stop = segments
    whole = crc_ok_spans(registers, begin, stop - begin)
    for index in np.flatnonzero(whole).tolist():  # mostly a 0x00 glitch, which keeps the CRC: no frame of its own
        whole[index] = whole_run_frame(data, int(begin[index]), int(stop[index]))
    counts = split - begin
    owner = np.repeat(np.arange(len(begin)), counts)
    positions = spread(begin, counts)
    starts, ends = checked_readings(data, registers, positions, stop[owner])
    of = np.searchsorted(begin, starts, side="right") - 1
    reached = whole.copy()
    reached[of[(ends > split[of]) | (ends < split[of])]] = True  # into the strays, or inside the frame
    if errors is not None and len(errors):
        after = errors + 1  # a frame may start after a framing error: inside the frame?
        at = np.searchsorted(begin, after, side="right") - 1
        inside = (at >= 0) & (after > begin[np.maximum(at, 0)]) & (after < split[np.maximum(at, 0)])
        reached[at[inside]] = True
    return reached
