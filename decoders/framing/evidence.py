"""The evidence the best parse weighs, and the candidate pieces it reads at a byte position.

Every reading of a run of bytes is scored in bits: the log2 of how much likelier the
reading makes the bytes than the alternative of noise. The weights, all in one place:

=====================  ======  ===============================================================
evidence               bits    why
=====================  ======  ===============================================================
CRC matches            +16     a random run passes CRC-16 with probability 2^-16
noise byte             -3      a byte no frame explains (roughly one byte in eight is noise
                               on a bad line; on a good one far fewer)
stray byte at a frame  -1      a transmitter's turn-on/turn-off glitch: one byte directly
                               before or after a frame (valid or damaged; on exact timing
                               with no pause between) is common on real RS485 lines
address 248-255        -3      reserved by the specification, yet used by many meters,
                               batteries and inverters (0xFE, 0xFF)
broadcast (address 0)  -1      for a function a master may broadcast (writes, diagnostics)
address 0, a read      -6      nobody can answer it
user-defined function  -3      65-72, 100-110: legal, rare
unknown function       -6      found only by CRC search, only where a boundary supports it
length by CRC search   -8      no length rule: ~256 lengths tried, 2^8 more chances to match
expected direction     +3      where the request and response rules give different lengths:
                               the response reading after a request to the same slave and
                               function, the request reading otherwise
retried request        +6      a request reading that repeats the open request byte for byte
                               (a master sends it again after its timeout): the answer
                               reading it competes with (its first bytes, then a 0x00
                               glitch) needs the slave's registers to spell the request
quantity out of range  -4      a read request (FC 1-4) asking for 0 or more than the
                               specification allows (2000 bits, 125 registers): only a faulty
                               master sends one (its slave answers exception 03), while an
                               answer and two 0x00 glitch bytes read as such a request too
silence > t1.5 at a    +1      exact timing only: a pause (or a segment end) where a piece
piece's start or end           starts or ends
silence > t1.5 inside  -4      exact timing only: each pause inside a frame
damaged frame          -10     a plausible header whose frame fails its CRC; allowed only
                               between supported boundaries (a segment end, a pause, a
                               valid frame), +4 when its length fits its rule (as
                               much as a pause inside it costs), +3 when it is the answer
                               the open request awaits (same slave and function)
USS telegram           +12     BCC (8 bits) plus STX and a NORD PPO length (4 bits)
framing error, noise   +2      a character the receiver saw with a framing error (a logic
                               analyzer's capture): a spike or a break on an idle line reads
                               as one, so as noise it costs 2 bits less, and the byte after
                               it is a supported boundary (a damaged frame may start there)
framing error at a     -4      a damaged frame whose first byte had a framing error: likelier
damaged frame's start          a glitch before the frame than its slave address (a CRC-valid
                               reading is not weighed: its CRC proves its bytes, and RS485
                               drivers that turn off early give valid frames a last byte
                               with a framing error)
=====================  ======  ===============================================================

A length found by CRC search counts only between supported boundaries too: its
start at a segment start, a pause or a valid frame's end, its end at a segment end,
a pause or the start of another valid reading. Random bytes pass a CRC
search about once in 256 tries (2^-16 per length, 256 lengths): unguarded, a noisy
line would be full of invented frames. One whose end nothing supports is no reading at
all: not even a frame start, where a damaged frame could not begin
(:mod:`decoders.framing.programme`).

Zero bytes after a frame keep its CRC register at zero, so every valid frame ending
in 0x00 has a CRC-valid prefix, and a frame followed by a 0x00 glitch a CRC-valid
longer reading. Where both readings fit a length rule (an FC 3 request ending in
0x00 whose first seven bytes read as a 7-byte answer; an 8-byte request and its
glitch as a 9-byte answer), the expected direction decides (+3 against the
glitch's -1 and a boundary's +1), unless the request reading is the open request
again: a master's retry after its timeout (+6). A longer reading that fits no rule (CRC search,
a whole run) is no candidate at all when a shorter prefix fits one: its CRC is no
evidence.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from fastcrc import crc16

from decoders.crc import crc_ok_lengths, prefix_registers
from decoders.frame import MODBUS, USS, FrameFlag
from decoders.framing.content import MAX_ADDRESS, MIN_ADU, OpenRequest, awaits, rule_lengths
from decoders.modbus.codecs import CODECS, LAYOUTS
from decoders.modbus.codes import DIAGNOSTICS, EXCEPTION_BIT, MAX_QUANTITY, USER_DEFINED_FUNCTIONS
from decoders.modbus.layouts import MAX_ADU
from decoders.uss import STX, uss_length

CRC_MATCH = 16.0
NOISE_BYTE = -3.0
GLITCH_BYTE = -1.0
ADDRESS_RESERVED = -3.0
ADDRESS_BROADCAST = -1.0
ADDRESS_BROADCAST_READ = -6.0
FUNCTION_USER_DEFINED = -3.0
FUNCTION_UNKNOWN = -6.0
LENGTH_SEARCHED = -8.0
EXPECTED_DIRECTION = 3.0
RETRIED_REQUEST = 6.0
QUANTITY_OUT_OF_RANGE = -4.0
#: The read functions whose request's quantity is weighed (their limits: ``MAX_QUANTITY``).
READ_FUNCTIONS = (1, 2, 3, 4)
BOUNDARY_SUPPORTED = 1.0
PAUSE_INSIDE = -4.0
DAMAGED = -10.0
DAMAGED_FITS_RULE = 4.0
USS_MATCH = 12.0
FRAMING_ERROR_NOISE = 2.0
FRAMING_ERROR_HEADER = -4.0

#: Functions a master may send to address 0 (every slave acts, none answers).
BROADCAST_FUNCTIONS = frozenset({5, 6, 8, 15, 16, 21, 22, 23})



def address_prior(address: int, function: int) -> float:
    """What an address says about a frame that starts with it."""
    if 1 <= address <= MAX_ADDRESS:
        return 0.0
    if address == 0:
        return ADDRESS_BROADCAST if function in BROADCAST_FUNCTIONS else ADDRESS_BROADCAST_READ
    return ADDRESS_RESERVED


def function_prior(function: int) -> float | None:
    """What a function code says; ``None`` for 0, which no frame carries."""
    code = function & ~EXCEPTION_BIT
    if code == 0:
        return None
    if code in CODECS:
        return 0.0
    if code in USER_DEFINED_FUNCTIONS:
        return FUNCTION_USER_DEFINED
    return FUNCTION_UNKNOWN


def quantity_prior(request: bytes) -> float:
    """What a read request's quantity says (``request``: at least its first six bytes)."""
    if request[1] not in READ_FUNCTIONS or len(request) < 6:
        return 0.0
    limit = MAX_QUANTITY[request[1]]
    quantity = request[4] << 8 | request[5]
    return 0.0 if 1 <= quantity <= limit else QUANTITY_OUT_OF_RANGE


def plausible_damaged_header(address: int, function: int) -> bool:
    """A header a damaged frame may have: a slave address (or broadcast) and a function that exists."""
    code = function & ~EXCEPTION_BIT
    return address <= MAX_ADDRESS and (code in CODECS or code in USER_DEFINED_FUNCTIONS)


def zero_padded(data: bytes, start: int, end: int) -> bool:
    """Whether ``data[start:end]`` ends in 0x00 bytes after a shorter CRC-valid prefix
    that is a frame by its length rule (the prefix of any valid frame ending in 0x00
    passes the CRC too, so the prefix must fit its rule to count)."""
    stop = end
    while stop > start + MIN_ADU and data[stop - 1] == 0:
        stop -= 1
        if crc16.modbus(data[start:stop]) == 0 and stop - start in rule_lengths(data[start:stop]):
            return True
    return False


def any_length_echo(head: bytes) -> bool:
    """Whether a frame starting with ``head`` is FC 8 sub-function 0 (return query data),
    which echoes any number of bytes."""
    return head[1] == DIAGNOSTICS and len(head) >= 4 and head[2] == 0 and head[3] == 0


def searchable(head: bytes, lengths: list[int | None] | None = None) -> bool:
    """Whether only CRC search can find this frame's length: no rule gives one, or
    :func:`any_length_echo`. ``lengths``: :func:`rule_lengths` of ``head``, where the caller
    has them already."""
    if head[1] == DIAGNOSTICS:
        return any_length_echo(head)
    return not any(length is not None for length in (rule_lengths(head) if lengths is None else lengths))


#: A reading's direction, where the request and response rules differ; ``SEARCHED``: a
#: length found by CRC search (taken only between supported boundaries).
NO_DIRECTION, REQUEST_READING, RESPONSE_READING, SEARCHED = 0, 1, 2, 3
#: (end, score without timing and direction, flags, protocol, direction)
Reading = tuple[int, float, FrameFlag, int, int]


def direction_bonus(direction: int, frame: bytes, open_request: OpenRequest) -> float:
    """The expected direction's evidence, and a retry's, for the reading ``frame`` (see the
    table above)."""
    if direction in (NO_DIRECTION, SEARCHED):
        return 0.0
    if not awaits(open_request, frame[0], frame[1]):
        return 0.0 if direction == RESPONSE_READING else EXPECTED_DIRECTION
    if direction == RESPONSE_READING:
        return EXPECTED_DIRECTION
    assert open_request is not None
    return RETRIED_REQUEST if frame == open_request[2] else 0.0


#: Runs shorter than this are CRC-searched by one ``fastcrc`` call per length.
SCALAR_SEARCH_BYTES = 1024


class CrcSearch:
    """CRC search over one run of bytes: every length at which a span from a given start
    passes the CRC, by numpy over the run's prefix registers (computed at the first search)."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self._registers: npt.NDArray[np.uint32] | None = None

    @property
    def registers(self) -> npt.NDArray[np.uint32]:
        """:func:`~decoders.crc.prefix_registers` of the run (computed once, and shared)."""
        if self._registers is None:
            self._registers = prefix_registers(self.data)
        return self._registers

    def lengths(self, start: int, stop: int) -> list[int]:
        """Lengths ``MIN_ADU..min(MAX_ADU, stop - start)`` whose span passes the CRC."""
        longest = min(MAX_ADU, stop - start)
        if len(self.data) < SCALAR_SEARCH_BYTES and self._registers is None:
            # A short run: prefix registers would cost more than the CRC calls.
            data = self.data
            return [n for n in range(MIN_ADU, longest + 1) if crc16.modbus(data[start : start + n]) == 0]
        return crc_ok_lengths(self.registers, start, MIN_ADU, longest)


def valid_frames_at(data: bytes, start: int, stop: int, *, search_unknown: bool, search: CrcSearch) -> list[Reading]:
    """CRC-valid readings starting at ``start`` within ``stop``. ``search_unknown``: CRC
    search for unknown function codes too (only where a boundary supports a frame
    start: they are tried at few places)."""
    if stop - start < MIN_ADU:
        return []
    found: list[Reading] = []
    if data[start] == STX:
        uss = uss_length(data[start : min(stop, start + MAX_ADU)])
        if uss is not None:
            found.append((start + uss, USS_MATCH, FrameFlag.NONE, USS, NO_DIRECTION))
    address, function = data[start], data[start + 1]
    prior = function_prior(function)
    if prior is None:
        return found
    prior += address_prior(address, function)
    head = data[start : min(stop, start + MAX_ADU)]
    lengths = rule_lengths(head)
    for position, length in enumerate(lengths):
        if length is None or not MIN_ADU <= length <= len(head) or crc16.modbus(head[:length]) != 0:
            continue
        direction = NO_DIRECTION if len(lengths) == 1 else (REQUEST_READING, RESPONSE_READING)[position]
        quantity = quantity_prior(head) if direction == REQUEST_READING else 0.0
        found.append((start + length, CRC_MATCH + prior + quantity, FrameFlag.NONE, MODBUS, direction))
    known = (function & ~EXCEPTION_BIT) in CODECS or (function & ~EXCEPTION_BIT) in USER_DEFINED_FUNCTIONS
    if (known or search_unknown) and searchable(head, lengths):
        score = CRC_MATCH + prior + LENGTH_SEARCHED
        for length in search.lengths(start, stop):
            if length not in lengths and not zero_padded(data, start, start + length):
                found.append((start + length, score, FrameFlag.NONE, MODBUS, SEARCHED))
    return found


def whole_run_frame(data: bytes, start: int, stop: int) -> bool:
    """A run that timing closes on both sides passes the CRC as a whole, fits no rule,
    and is not a shorter frame padded with zeros: one frame of a bad length."""
    length = stop - start
    if not MIN_ADU <= length <= MAX_ADU or crc16.modbus(data[start:stop]) != 0 or zero_padded(data, start, stop):
        return False
    return length not in rule_lengths(data[start:stop]) and function_prior(data[start + 1]) is not None


def damaged_flags(head: bytes, *, open_request: OpenRequest, at_capture_end: bool) -> tuple[FrameFlag, bool]:
    """How a CRC-bad frame of ``len(head)`` bytes reads: (flag, fits its rule).

    ``truncated`` if its rule wants more bytes (a response to the open request is read
    as one first: an answer cut short is not a damaged request); ``bad_length`` if less.
    """
    lengths = rule_lengths(head)
    if not lengths:
        return FrameFlag.NONE, False
    size = len(head)
    longer = any(length is None or length > size for length in lengths)
    if awaits(open_request, head[0], head[1]) and len(lengths) == 2:
        response = lengths[1]
        if response is None or response > size:
            return FrameFlag.TRUNCATED, False
        return (FrameFlag.NONE, True) if response == size else (FrameFlag.BAD_LENGTH, False)
    if size in lengths and not (at_capture_end and longer):
        return FrameFlag.NONE, True
    return (FrameFlag.TRUNCATED if longer else FrameFlag.BAD_LENGTH), False


#: Per function code: the length rules a clean frame may have, as (fixed, position, base)
#: triples; a frame is clean when one of them gives a CRC-valid length (see best_parse).
CleanRule = tuple[int, int, int]


def _clean_rules() -> list[tuple[CleanRule, ...]]:
    table: list[tuple[CleanRule, ...]] = [() for _ in range(256)]
    for function, layout in LAYOUTS.items():
        rules: list[CleanRule] = []
        for rule in (layout.request, layout.response):
            if rule.fixed is not None:
                triple = (rule.fixed, 0, 0)
            elif rule.position is not None and rule.size == 1:
                triple = (0, rule.position, rule.base)
            else:
                continue  # FC 24's two-byte count, FC 43's objects: the parser's business
            if triple not in rules:
                rules.append(triple)
        table[function] = tuple(rules)
        if function != 43:
            table[function | EXCEPTION_BIT] = ((5, 0, 0),)
    return table


CLEAN_RULES = _clean_rules()
