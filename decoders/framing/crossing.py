"""Anchors no reading crosses into the bytes the programme parses between them.

An anchor (:mod:`decoders.framing.best_parse`) is on every best parse because reading its bytes
any other way gives up its CRC, and the programme then runs over the bytes between anchors
alone: a *gap* (stray bytes, noise, a damaged frame; the bytes before the first anchor and after
the last count too). That holds only where nothing the programme over the whole segment weighs
reaches across a gap's edge. Where two anchors touch, nothing that crosses them wins: a reading
across their edge gives up two CRCs for one (and a direction's or a retry's evidence, +3 or +6,
never makes up 16 bits). Next to a gap it may win, and even where it loses it changes what the
programme weighs inside the gap: its end is a boundary a damaged frame may start at or a searched
length may end at, its start a frame start a damaged frame ends before. So an anchor goes, and
its bytes join the gaps around it, where any of these holds (until none does):

1. a reading from inside a gap ends past it (in the anchor after it, or further): the programme
   over the gap cuts that reading off. The programme over a gap before an anchor reads every
   reading the programme over the whole segment reads there, and says so
   (:func:`decoders.framing.programme.best_pieces_before_anchor`): the anchor goes, and the
   programme runs on to the next one;
2. a CRC-valid reading by a length rule (any address, an exception) or a USS telegram from
   before a gap's start ends past it (it starts inside the anchor before the gap, or further
   back);
3. a frame may start inside the anchor, within reach of a gap (a reading ends there, or a
   character with a framing error comes just before): a damaged frame or a CRC search from
   there may reach into the gap, and the programme over the gap does not see it start;
4. the whole segment passes the CRC as a frame of a bad length (a reading across every anchor).

Each needs a CRC coincidence near a gap (about 1 in 65 536 per reading tried, 1 in 256 for a CRC
search) or a framing error inside a frame: the anchors of a clean bus stay, and the programme's
bytes grow by a frame now and then. The programme over a gap gives a frame ending at the anchor
after it no boundary's evidence (:meth:`decoders.framing.programme._Programme._supported`): the
programme over the whole segment sees no boundary there either. Frames and stray bytes cut in
bulk (:func:`decoders.framing.fast.frame_pair_segments`) follow rules 2 to 4 too.
``tests/property/test_crossing_readings.py`` holds the fast path to the programme over the whole
segment (``fast=False``) on segments built to hold such readings.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.capture import Int64Array
from decoders.framing import evidence as ev
from decoders.framing.content import MAX_ADDRESS
from decoders.framing.programme import Context
from decoders.framing.rule_tables import OWN_RULE, checked_readings, rule_readings, uss_telegrams
from decoders.modbus.layouts import MAX_ADU
from decoders.uss import STX


def uncrossed(data: bytes, context: Context, search: ev.CrcSearch, anchors: tuple[Int64Array, Int64Array],
              known: list[tuple[Int64Array, Int64Array]] | None = None) -> npt.NDArray[np.bool_]:
    """Which of the ``anchors`` (starts and stops, in order) no reading crosses into a gap by
    rules 2 to 4 (see the module docstring; rule 1 is the programme's). ``known``: the CRC-valid
    readings by rule of addresses 1 to 247 at every position, where the caller found them
    (:func:`~decoders.framing.fast.clean_frame_ends`): only the others are looked for."""
    starts, stops = anchors
    kept = np.ones(len(starts), np.bool_)
    end = len(data)
    if not len(starts) or _tiled(starts, stops, end):
        return kept
    if context.timed and context.closed and ev.whole_run_frame(data, 0, end):
        kept[:] = False  # 4: one reading over every anchor
        return kept
    readings = _Readings(data, search.registers, known)
    passed: set[int] = set()  # anchors checked: rules 2 and 3 read their bytes and those before them
    while True:
        at = np.flatnonzero(kept)
        begins = np.concatenate([[0], stops[at]])
        ends = np.concatenate([starts[at], [end]])
        before_gaps = [k - 1 for k in np.flatnonzero(ends > begins).tolist() if k > 0 and int(at[k - 1]) not in passed]
        crossed = [int(at[k]) for k in _reached_into(context, readings, (starts[at], stops[at]), before_gaps)]
        passed.update(int(at[k]) for k in before_gaps)
        if not crossed:
            return kept
        kept[crossed] = False


class _Readings:
    """The readings rules 2 and 3 weigh, from given starts: CRC-valid by rule, or USS."""

    def __init__(self, data: bytes, registers: npt.NDArray[np.uint32],
                 known: list[tuple[Int64Array, Int64Array]] | None) -> None:
        self.data, self.registers = data, registers
        self._known: tuple[Int64Array, Int64Array] | None = None
        if known is not None:
            none = np.zeros(0, np.int64)
            self._known = (np.concatenate([none, *(starts for starts, _ in known)]),
                           np.concatenate([none, *(ends for _, ends in known)]))

    def starting(self, near: npt.NDArray[np.bool_]) -> tuple[Int64Array, Int64Array]:
        """Starts and ends of the readings starting where ``near`` holds (per position)."""
        end = len(self.data)
        positions = np.flatnonzero(near[:end])
        if self._known is None:
            return checked_readings(self.data, self.registers, positions, np.full(len(positions), end, np.int64))
        wire = np.frombuffer(self.data, np.uint8)
        heads = wire[positions]
        functions = wire[np.minimum(positions + 1, end - 1)]
        # What clean_frame_ends did not read: other addresses, rules of their own, USS telegrams.
        other = positions[(heads - np.uint8(1) >= np.uint8(MAX_ADDRESS)) | OWN_RULE[functions]]
        stx = positions[heads == STX]
        limits = np.full(max(len(other), len(stx)), end, np.int64)
        by_rule = rule_readings(self.data, self.registers, other, limits[: len(other)])
        telegrams = uss_telegrams(self.data, stx, limits[: len(stx)])
        known_starts, known_ends = self._known
        taken = near[known_starts]
        return (np.concatenate([by_rule[0], telegrams[0], known_starts[taken]]),
                np.concatenate([by_rule[1], telegrams[1], known_ends[taken]]))


def _tiled(starts: Int64Array, stops: Int64Array, end: int) -> bool:
    """Whether the anchors cover every byte (no gap)."""
    return bool(starts[0] == 0 and stops[-1] == end and (starts[1:] == stops[:-1]).all())


def _reached_into(context: Context, readings: _Readings, anchors: tuple[Int64Array, Int64Array],
                  which: list[int]) -> list[int]:
    """Of the anchors (the anchors kept), given ``which`` of them are followed by a gap: those
    a reading from before the gap reaches past (2), and those a frame may start inside within
    reach of a gap (3): indexes into ``anchors``."""
    if not which:
        return []
    starts, stops = anchors[0][which], anchors[1][which]
    end = len(readings.data)
    window = np.zeros(end + 1, np.int64)  # every start a reading past these anchors' ends may have
    np.add.at(window, np.maximum(starts - MAX_ADU, 0), 1)
    np.add.at(window, stops, -1)
    near = np.cumsum(window) > 0
    reading_starts, reading_ends = readings.starting(near)
    # An anchor's end strictly inside a reading: crossed (``stops`` are in order).
    crossings = np.zeros(len(which) + 1, np.int64)
    np.add.at(crossings, np.searchsorted(stops, reading_starts, side="right"), 1)
    np.add.at(crossings, np.searchsorted(stops, reading_ends, side="left"), -1)
    reached = [anchor for anchor, hit in zip(which, (np.cumsum(crossings[:-1]) > 0).tolist(), strict=True) if hit]
    # 3: frame starts near a gap: a reading's end, or the byte after a framing error.
    supports = np.concatenate([reading_ends, np.array(context.framing_errors, np.int64) + 1])
    supports = supports[near[np.minimum(supports, end)]]
    holding = np.searchsorted(anchors[0], supports, side="left") - 1
    inside = (holding >= 0) & (supports < anchors[1][np.maximum(holding, 0)])
    return sorted({*reached, *holding[inside].tolist()})
