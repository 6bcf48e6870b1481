"""The length rules as lookup tables, and the readings they prove at any positions.

A length rule gives a frame's length from its function code and, for some, a byte count (one
byte at a fixed place): :class:`RuleTable` holds a direction's rules as two arrays derived from
:data:`decoders.modbus.codecs.LAYOUTS`, so that numpy reads the lengths of many frames at once
(:mod:`decoders.framing.fast`, :mod:`decoders.framing.delivery`, :mod:`decoders.modbus.shapes`).
:func:`checked_readings` finds the readings a check proves (CRC-valid by a rule, a USS
telegram's BCC) at given positions: :mod:`decoders.framing.crossing` weighs them against
anchors. The rules the tables cannot hold (``OWN_RULE``) are read by the scalar rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.capture import Int64Array
from decoders.crc import crc_ok_spans
from decoders.framing.content import MIN_ADU, rule_lengths
from decoders.modbus.codecs import LAYOUTS
from decoders.modbus.codes import EXCEPTION_BIT
from decoders.modbus.layouts import EXCEPTION_LENGTH, MAX_ADU, LengthRule
from decoders.uss import PPO_LGE, STX, uss_length

#: Bytes read past a segment's start to find byte counts (FC 23's sits at 10).
_PAD = 16
#: A direction without a rule, in the tables.
NO_RULE = -1


@dataclass(frozen=True)
class RuleTable:
    """A length rule per function code, ``base + scale * byte[position]`` (a fixed length:
    scale 0 and position 0, which every segment has), as two arrays: ``position`` by function
    code, and the rule's length by function code and byte read (``-1``: no rule)."""

    position: npt.NDArray[np.intp]
    #: ``length[function << 8 | byte]``, narrow so that the table (128 kB) stays in the cache.
    length: npt.NDArray[np.int16]

    @classmethod
    def build(cls, direction: str) -> RuleTable:
        position = np.zeros(256, np.intp)
        length = np.full((256, 256), NO_RULE, np.int16)
        for function, layout in LAYOUTS.items():
            rule: LengthRule = getattr(layout, direction)
            if rule.fixed is not None:
                length[function] = rule.fixed
            elif rule.position is not None and rule.size == 1:
                # A byte count comes before at least itself and the CRC: a rule's length is past
                # its position, which :meth:`fits` needs.
                assert rule.base > rule.position
                position[function] = rule.position
                length[function] = rule.base + np.arange(256)
        return cls(position, length.ravel())

    def fits(self, padded: npt.NDArray[np.uint8], starts: Int64Array, functions: npt.NDArray[np.intp],
             seg_lengths: Int64Array) -> npt.NDArray[np.bool_]:
        """Whether each segment is as long as this table's rule for its function code says.
        A byte count read past a segment's end (from the next bytes or the padding) never makes
        it fit: its rule's length is longer than its position, so than the segment."""
        keys = (functions << 8) | padded[starts + self.position.take(functions)]
        fitting: npt.NDArray[np.bool_] = self.length.take(keys) == seg_lengths
        return fitting


REQUEST_RULES = RuleTable.build("request")
RESPONSE_RULES = RuleTable.build("response")
_HAS_LAYOUT = np.zeros(256, np.bool_)
_HAS_LAYOUT[list(LAYOUTS)] = True
#: The Altivar's FC 43 negative answer is 6 bytes, not 5; the parser handles it.
PLAIN_EXCEPTION = _HAS_LAYOUT.copy()
PLAIN_EXCEPTION[43] = False


def padded_bytes(data: bytes) -> npt.NDArray[np.uint8]:
    """``data`` as a byte array with room to read a few bytes past any frame start."""
    return np.frombuffer(data + bytes(_PAD), np.uint8)


#: Per function code: whether its length rule is one the tables cannot hold (a two-byte count,
#: FC 43's objects, the Altivar's FC 43 negative answer), for :func:`whole_by_own_rule`.
OWN_RULE = np.zeros(256, np.bool_)
OWN_RULE[[24, 43, 43 | EXCEPTION_BIT]] = True


def checked_readings(
    data: bytes, registers: npt.NDArray[np.uint32], positions: Int64Array, limits: Int64Array
) -> tuple[Int64Array, Int64Array]:
    """The readings starting at ``positions`` that a check proves: CRC-valid by a length rule
    (either direction, an exception, any address) or a USS telegram (its BCC), as
    :func:`decoders.framing.evidence.valid_frames_at` reads them (all but CRC searches), each
    within its limit (``limits``, per position): their starts and ends. Two rules giving one
    length are one reading. ``registers``: :func:`prefix_registers` of ``data``."""
    starts, ends = rule_readings(data, registers, positions, limits)
    uss_starts, uss_ends = uss_telegrams(data, positions, limits)
    return np.concatenate([starts, uss_starts]), np.concatenate([ends, uss_ends])


_PPO_LENGTH = np.zeros(256, np.bool_)
_PPO_LENGTH[list(PPO_LGE)] = True


def uss_telegrams(data: bytes, positions: Int64Array, limits: Int64Array) -> tuple[Int64Array, Int64Array]:
    """Starts and ends of the USS telegrams at ``positions``, each within its limit."""
    wire = np.frombuffer(data, np.uint8)  # read in place: positions are few, a padded copy costs more
    candidates = np.flatnonzero((wire[positions] == STX) & _PPO_LENGTH[wire[np.minimum(positions + 1, len(wire) - 1)]])
    telegrams = [(start, start + length) for start, stop in zip(positions[candidates].tolist(),
                                                                limits[candidates].tolist(), strict=True)
                 if (length := uss_length(data[start : min(stop, start + MAX_ADU)])) is not None]
    found = np.array(telegrams, np.int64).reshape(-1, 2)
    return found[:, 0], found[:, 1]


def rule_readings(
    data: bytes, registers: npt.NDArray[np.uint32], positions: Int64Array, limits: Int64Array
) -> tuple[Int64Array, Int64Array]:
    """:func:`checked_readings` by rule."""
    # Read in place, as has_own_rule reads: a byte count past the end (read at the last byte
    # instead) gives a length past it too, which no limit lets through.
    wire = np.frombuffer(data, np.uint8)
    last = len(wire) - 1
    inside = positions + MIN_ADU <= limits
    positions, limits = positions[inside], limits[inside]
    raw = wire[positions + 1].astype(np.intp)
    own = OWN_RULE[raw]
    exception = ((raw & EXCEPTION_BIT) != 0) & ~own
    tabled = ~own & ~exception
    at, functions = positions[tabled], raw[tabled]
    request = REQUEST_RULES.length.take(
        (functions << 8) | wire[np.minimum(at + REQUEST_RULES.position.take(functions), last)])
    response = RESPONSE_RULES.length.take(
        (functions << 8) | wire[np.minimum(at + RESPONSE_RULES.position.take(functions), last)])
    other = response != request  # one length by both rules: one reading
    plain = exception & PLAIN_EXCEPTION[raw & ~EXCEPTION_BIT]
    starts = [at, at[other], positions[plain]]
    lengths = [request.astype(np.int64), response[other].astype(np.int64), np.full(int(plain.sum()), EXCEPTION_LENGTH)]
    ends = [limits[tabled], limits[tabled][other], limits[plain]]
    for begin, stop in zip(positions[own].tolist(), limits[own].tolist(), strict=True):
        found = [n for n in rule_lengths(data[begin : min(stop, begin + MAX_ADU)]) if n is not None]
        starts.append(np.full(len(found), begin, np.int64))
        lengths.append(np.array(found, np.int64))
        ends.append(np.full(len(found), stop, np.int64))
    start, length, limit = np.concatenate(starts), np.concatenate(lengths), np.concatenate(ends)
    usable = (length >= MIN_ADU) & (length <= MAX_ADU) & (start + length <= limit)
    start, length = start[usable], length[usable]
    valid = crc_ok_spans(registers, start, length)
    return start[valid], (start + length)[valid]
