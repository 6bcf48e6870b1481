"""A segment that is one frame ending in 0x00 and, a byte shorter, a frame of the other
direction and a 0x00 glitch: the two readings weighed without the programme.

Zero bytes after a frame keep its CRC valid (:mod:`decoders.framing.evidence`), so an FC 3
request ending in 0x00 whose first seven bytes fit an answer reads as that answer and a glitch,
and a 9-byte FC 3 answer ending in 0x00 as a request and a glitch. On a polling bus about one
frame in 3 000 is such a segment, and the programme over it cost a large share of all the
framing of a polling capture; weighed here, a fraction of that.

When nothing else in the segment can be read -- no CRC-valid span and no USS telegram starts
after its first byte, no pause and no framing error lies inside, and its first byte starts
exactly the two rule readings -- the programme's best path is one of these two: any other path
is noise bytes alone, which score below zero, where either reading scores at least 2 bits (a CRC's
16, less 6 for a read sent to address 0, 3 for a user-defined function, 4 for a quantity out of
range and 1 for the glitch). Each path's score is the sum the programme adds up along it:

- the whole frame: its reading's evidence (:func:`~decoders.framing.evidence.valid_frames_at`),
  the expected direction or a retry (:func:`~decoders.framing.evidence.direction_bonus`), and
  the segment's end as a supported boundary (+1);
- the shorter frame and the glitch: its reading's evidence, its direction bonus, and the glitch
  byte directly after it (-1).

A tie goes to the whole frame, as in the programme, where the first path to reach the end keeps
it. The weights stay in :mod:`decoders.framing.evidence`; the tests hold this to the programme
(``parse_segment(..., fast=False)``) on segments of every kind of open request.
"""

from __future__ import annotations

from decoders.frame import MODBUS, FrameFlag
from decoders.framing import evidence as ev
from decoders.framing.content import MIN_ADU, OpenRequest, after_frame
from decoders.framing.programme import Context
from decoders.modbus.layouts import MAX_ADU
from decoders.uss import STX, uss_length

_RULE_DIRECTIONS = {ev.REQUEST_READING, ev.RESPONSE_READING}


def weighed_zero_end(data: bytes, context: Context, open_request: OpenRequest) -> tuple[bool, OpenRequest] | None:
    """Whether the closed segment ``data`` is the shorter frame and a glitch (else the whole
    frame), and the open request after it, where it is such a segment (see the module
    docstring); ``None`` where the programme must weigh it."""
    size = len(data)
    if (not context.closed or context.pauses or context.framing_errors or not MIN_ADU < size <= MAX_ADU
            or data[-1] != 0):
        return None
    search = ev.CrcSearch(data)
    readings = ev.valid_frames_at(data, 0, size, search_unknown=True, search=search)
    if len(readings) != 2 or {end for end, *_ in readings} != {size, size - 1}:
        return None
    if any(flags != FrameFlag.NONE or protocol != MODBUS or direction not in _RULE_DIRECTIONS
           for _, _, flags, protocol, direction in readings):
        return None
    if not nothing_read_after_first_byte(data, search):
        return None
    (whole,) = (reading for reading in readings if reading[0] == size)
    (shorter,) = (reading for reading in readings if reading[0] == size - 1)
    whole_score = whole[1] + ev.direction_bonus(whole[4], data, open_request) + ev.BOUNDARY_SUPPORTED
    shorter_score = shorter[1] + ev.direction_bonus(shorter[4], data[:-1], open_request) + ev.GLITCH_BYTE
    if shorter_score > whole_score:
        return True, after_frame(data[:-1], open_request)
    return False, after_frame(data, open_request)


def nothing_read_after_first_byte(data: bytes, search: ev.CrcSearch) -> bool:
    """Whether no reading can start after the first byte of ``data`` (``search``: its CRC
    search): every one needs a CRC-valid span (a Modbus frame, by rule or by search) or a USS
    telegram."""
    size = len(data)
    for start in range(1, size - MIN_ADU + 1):
        if data[start] == STX and uss_length(data[start:]) is not None:
            return False
        if search.lengths(start, size):
            return False
    return True
