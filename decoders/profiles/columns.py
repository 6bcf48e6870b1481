"""Profiles applied as array lookups: which frames of named slaves stay in columns.

Where a profile names a slave's registers, the frames the annotator keeps in columns
(:mod:`decoders.modbus.columnar`) get their names at once, as lookups of each distinct
param (:mod:`decoders.profiles.column_names`). This module says which frames may be named so,
and by which profile.

The annotator cuts a batch after each frame that changes what the profiles name
(:func:`first_change`: an identification that gives its slave another profile, a frame that
teaches its slave's scanner tables a mapping they do not hold), so that every frame of a part is
named by the profiles as they stand at its start: in one step, nothing predicted. Within a part,
a named slave's frame stays in columns only where naming it is that lookup alone, all that
:meth:`~decoders.profiles.apply.ProfileApplier.apply_decoding` would do to it:

* none of its registers is a scanner table's address register (:func:`unnameable`: one may teach
  the table, and the plain path learns from it);
* it carries every register of each parameter over several registers it names, or none
  (:func:`unnameable`: a frame carrying part of one gets a remark), and names no string (its
  value is text of any length: named one by one);
* a request the profile remarks nothing of (:func:`unnameable`: a function it supports, counts
  within its limits; answers in columns are never exceptions, which may get remarks);
* its profile names no two registers alike and names none by a number (:func:`plain_codes`):
  the MCAP params message holds a frame's values by code, or by address where none names it.

The annotator leaves the frames :func:`unnameable` finds out and finds the columns again. The
tests hold every output of frames so named to the plain path (``tests/property/test_columnar.py``,
``tests/property/test_decoded_texts.py``, ``tests/test_columnar_outputs.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from decoders.memo import KeptByIdentity
from decoders.message import NONE, ROLE_CODE, ROLE_ORDER, MessageBatch, Role
from decoders.modbus.codecs import parse_as, parse_pdu
from decoders.modbus.codes import BIT_FUNCTIONS
from decoders.modbus.columnar import ColumnarFrames, one_of
from decoders.modbus.columnar_text import READ, READ_WRITE, WRITE, words_at
from decoders.modbus.param_runs import named_registers
from decoders.modbus.pdu import Pdu
from decoders.modbus.pdu_serial import DeviceIdResponse
from decoders.profiles.apply import (
    FrameFacts,
    ProfileApplier,
    knows_nothing,
    limit_remarks,
    product_code,
    request_addresses,
)
from decoders.profiles.model import Indirection, Profile

#: The request of an answer from before the batch, by its frame index (``None``: not kept).
EarlierRequest = Callable[[int], "Pdu | None"]
#: Frames that may be requests, and what the plain path may read as one (a frame of no known role).
_ASKING = [ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST], ROLE_CODE[Role.UNKNOWN]]
#: Functions whose requests name registers: where their first address and count lie.
_NAMING = (3, 4, 6, 16, 23)
_SHORTEST_NAMING = 6  # slave, function, address, count
_READ_WRITE, _READ_WRITE_NAMING = 23, 10  # FC 23 names a second span, written, at bytes 6 to 9
#: Read Device Identification (FC 43): an answer may give its slave a profile.
IDENTIFICATION = 43


def plain_codes(profile: Profile) -> bool:
    """Whether ``profile`` names each register by a code of its own that is not a number (a
    frame's values, keyed by code or else by address, then never share a key)."""
    # A parameter without a code (``--registers``'s) is keyed by its address, as unnamed ones are.
    codes = [parameter.code for parameter in profile.parameters.values() if parameter.code]
    return len(set(codes)) == len(codes) and not any(code.isdigit() for code in codes)


@dataclass(frozen=True)
class FrameProfiles:
    """The profile each frame of a batch is named by, its slave's now: ``profiles``, each
    distinct one; ``adds_nothing``, whether it leaves a frame as it is
    (:func:`~decoders.profiles.apply.knows_nothing`); ``place``, each frame's."""

    profiles: list[Profile]
    adds_nothing: npt.NDArray[np.bool_]
    place: npt.NDArray[np.int64]

    def of(self, position: int) -> Profile:
        return self.profiles[int(self.place[position])]

    def head(self, stop: int) -> FrameProfiles:
        """The profiles of the frames before position ``stop`` (a part cut from the batch)."""
        return FrameProfiles(self.profiles, self.adds_nothing, self.place[:stop])


def frame_profiles(applier: ProfileApplier, batch: MessageBatch) -> FrameProfiles:
    """The :class:`FrameProfiles` of ``batch``, with the profiles ``applier`` holds now."""
    book = applier.book
    # Each slave's place by a table indexed by slave + 1 (-1, no slave, to 255), not by a sort
    # of the batch's slaves.
    codes = batch.slave.astype(np.int64) - NONE
    table = np.zeros(int(codes.max(initial=0)) + 1, np.int64)
    profiles: list[Profile] = []
    places: dict[int, int] = {}  # by each distinct profile's identity, its place in ``profiles``
    for code in np.flatnonzero(np.bincount(codes)).tolist():
        profile = book.profile_for(None if code + NONE == NONE else code + NONE)
        if id(profile) not in places:
            places[id(profile)] = len(profiles)
            profiles.append(profile)
        table[code] = places[id(profile)]
    return FrameProfiles(profiles, np.array([knows_nothing(profile) for profile in profiles], np.bool_), table[codes])


def first_change(applier: ProfileApplier, batch: MessageBatch, earlier: EarlierRequest,
                 framed: FrameProfiles) -> int | None:
    """The position of the first frame of ``batch`` (``framed``: its profiles now) after which its
    profiles name otherwise: an
    identification (a valid FC 43 answer) that gives its slave another profile
    (:meth:`~decoders.profiles.book.ProfileBook.profile_after`), or a frame that teaches its
    slave's scanner tables (:func:`_teaching`); ``None`` where none does."""
    book = applier.book
    identified = [position for slave, found in _identifications(batch).items() for position, product in found
                  if book.profile_after(slave, product) is not book.profile_for(slave)]
    first = min(identified, default=None)
    taught = _teaching(applier, batch, earlier, framed, len(batch) if first is None else first)
    return taught if taught is not None else first


def _identifications(batch: MessageBatch) -> dict[int, list[tuple[int, str]]]:
    """By slave, the position and product code of each identification (a valid FC 43 answer
    giving one) in ``batch``, in order: what the plain path identifies a slave by."""
    frames = batch.frames
    offsets, data = frames.offsets, frames.data
    found: dict[int, list[tuple[int, str]]] = {}
    positions = np.flatnonzero((batch.function == IDENTIFICATION) & (batch.slave != NONE) & frames.crc_ok)
    for position, role, slave in zip(positions.tolist(), batch.role[positions].tolist(),
                                     batch.slave[positions].tolist(), strict=True):
        pdu = parse_as(data[offsets[position] : offsets[position + 1]], ROLE_ORDER[role])
        product = product_code(pdu) if isinstance(pdu, DeviceIdResponse) else None
        if product is not None:
            found.setdefault(slave, []).append((position, product))
    return found


class ColumnProfiles:
    """The profile of each frame kept in columns (``profile``: its place in ``profiles``, as
    :class:`FrameProfiles` has it), and whether it names anything (``named``)."""

    def __init__(self, framed: FrameProfiles, positions: npt.NDArray[np.int64]) -> None:
        self.profiles = framed.profiles
        self.profile: npt.NDArray[np.int64] = framed.place[positions]
        self.named: npt.NDArray[np.bool_] = ~framed.adds_nothing[self.profile]


def _teaching(applier: ProfileApplier, batch: MessageBatch, earlier: EarlierRequest, framed: FrameProfiles,
              before: int) -> int | None:
    """The first position before ``before`` of a frame that would change its slave's scanner
    tables (:meth:`~decoders.profiles.apply.ProfileApplier.would_learn`): a request (or a frame of
    no known role, which the plain path may read as one) naming an address register of its
    profile's tables, an answer to one, or an answer to a request from before the batch
    (``earlier``) naming one, that carries another address than the table holds now. A master
    that reads back or writes again the mapping it set (a PLC, every cycle) teaches nothing new."""
    if not any(profile.indirections for profile in framed.profiles):
        return None
    # Each profile's tables by their place in ``kinds`` (0: none); each frame's.
    kinds: list[tuple[Indirection, ...]] = [()]
    for profile in framed.profiles:
        if profile.indirections not in kinds:
            kinds.append(profile.indirections)
    frame_kind = np.array([kinds.index(profile.indirections) for profile in framed.profiles], np.int64)[framed.place]
    asks = np.zeros(len(batch), np.bool_)  # the frames of either span (a mask: no sort)
    for rows, low, count in _asked_spans(batch, frame_kind):
        kind = frame_kind[rows]
        hit = np.zeros(len(rows), np.bool_)
        for place, indirections in enumerate(kinds):
            for table in indirections:
                hit |= (kind == place) & overlap(low, low + count, table.address_registers, table.count)
        asks[rows[hit]] = True
    first = batch.frames.first_index
    requests = np.flatnonzero(asks)
    # What each teaching frame is read against: an answer, its request (a position in the batch,
    # or a PDU from before it); every other frame, nothing.
    teaching: list[tuple[int, int | Pdu | None]] = [(position, None) for position in requests.tolist()]
    answers = np.flatnonzero(np.isin(batch.request_index, requests + first))
    teaching += zip(answers.tolist(), (batch.request_index[answers] - first).tolist(), strict=True)
    for position in np.flatnonzero((batch.request_index != NONE) & (batch.request_index < first)).tolist():
        request = earlier(int(batch.request_index[position]))
        if any(0 <= address - table.address_registers < table.count
               for table in framed.of(position).indirections for address in request_addresses(request)):
            teaching.append((position, request))
    return next((position for position, request in sorted(teaching, key=lambda item: item[0])
                 if position < before and _teaches(applier, batch, framed, position, request)), None)


def _teaches(applier: ProfileApplier, batch: MessageBatch, framed: FrameProfiles, position: int,
             request: int | Pdu | None) -> bool:
    """Whether the frame at ``position`` (an answer read against ``request``: its position in
    the batch, or its PDU) carries scanner addresses its slave's tables do not hold now, read as
    the plain path reads it."""
    frames = batch.frames

    def pdu_at(at: int) -> Pdu:
        return parse_as(frames.data[int(frames.offsets[at]) : int(frames.offsets[at + 1])],
                        ROLE_ORDER[int(batch.role[at])])

    asked = pdu_at(request) if isinstance(request, int) else request
    return applier.would_learn(framed.of(position), int(batch.slave[position]),
                               [(param.address, param.raw) for param in named_registers(pdu_at(position), asked)])


def _asked_spans(batch: MessageBatch, frame_kind: npt.NDArray[np.int64]) -> list[tuple[npt.NDArray[np.int64], ...]]:
    """The registers the frames of ``batch`` that may be requests name, of profiles with tables
    (``frame_kind``, by frame, not 0): their positions, first registers and counts, once for every
    such frame and again for the written span of each FC 23."""
    frames = batch.frames
    starts, lengths = frames.offsets[:-1], np.diff(frames.offsets)
    asking = np.flatnonzero(one_of(batch.role, _ASKING) & one_of(batch.function, _NAMING)
                            & (lengths >= _SHORTEST_NAMING) & (batch.slave != NONE) & (frame_kind > 0))
    raw = np.frombuffer(frames.data, np.uint8)
    at = starts[asking]
    both = asking[(batch.function[asking] == _READ_WRITE) & (lengths[asking] >= _READ_WRITE_NAMING)]
    return [(asking, words_at(raw, at + 2), np.where(batch.function[asking] == 6, 1, words_at(raw, at + 4))),
            (both, words_at(raw, starts[both] + 6), words_at(raw, starts[both] + 8))]


def unnameable(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames,
               framed: FrameProfiles) -> npt.NDArray[np.int64]:
    """The positions of the frames of ``columnar`` (found in ``batch``) whose naming is more
    than a lookup: a scanner table's address register, a register of a parameter over several,
    or a request the profile remarks on."""
    slaves = ColumnProfiles(framed, columnar.positions)
    bad = np.zeros(len(columnar), np.bool_)
    if not slaves.named.any():
        return columnar.positions[bad]
    # The registers each frame names: its span, and an FC 23 request's read span (none elsewhere).
    spans = [(columnar.address, columnar.address + np.maximum(columnar.count, 0)),
             (columnar.read_address, columnar.read_address + columnar.read_count)]
    registers = ~one_of(columnar.function, BIT_FUNCTIONS)
    for place, profile in enumerate(slaves.profiles):
        of = slaves.named & (slaves.profile == place)
        for table in profile.indirections:
            for low, high in spans:
                bad |= of & overlap(low, high, table.address_registers, table.count)
        if profile.words_of:
            layout = WIDE_LAYOUTS.of(profile)
            for low, high in spans:
                bad |= of & registers & layout.unnameable(low, high)
    requests = np.flatnonzero(slaves.named & one_of(columnar.kind, (READ, WRITE, READ_WRITE)) & ~bad)
    if len(requests):
        # A request's remarks depend on its profile, function and counts alone: one of each asked.
        key = ((slaves.profile[requests] << 48) | (columnar.read_count[requests] << 32)
               | (columnar.function[requests] << 16) | columnar.count[requests])
        _, inverse = np.unique(key, return_inverse=True)  # no return_index: its stable sort costs more
        first = np.empty(int(inverse.max()) + 1, np.int64)
        first[inverse] = np.arange(len(inverse))  # a row of each key (any: the key decides)
        remarked = np.array([_remarked(applier, batch, slaves.profiles[int(slaves.profile[row])],
                                       int(columnar.positions[row])) for row in requests[first].tolist()], np.bool_)
        bad[requests[remarked[inverse]]] = True
    return columnar.positions[bad]


def _remarked(applier: ProfileApplier, batch: MessageBatch, profile: Profile, position: int) -> bool:
    """Whether ``profile`` remarks on the request at ``position``."""
    frames = batch.frames
    data = frames.data[int(frames.offsets[position]) : int(frames.offsets[position + 1])]
    facts = FrameFacts(int(batch.slave[position]), Role.REQUEST, int(batch.function[position]), True)
    return bool(limit_remarks(profile, facts, parse_pdu(data, is_request=True)))


class WideLayout(NamedTuple):
    """Where a profile's parameters over several registers lie, by register (a read may name up
    to 125 registers past 65 535): ``word``, its place in its parameter (-1: none); ``size``,
    the parameter's registers (0: none); ``texts``, how many registers of strings lie before
    it."""

    word: npt.NDArray[np.int16]
    size: npt.NDArray[np.int16]
    texts: npt.NDArray[np.int64]

    def at(self, address: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int16], npt.NDArray[np.int16]]:
        """The place and size of each register at ``address``."""
        return self.word[address], self.size[address]

    def unnameable(self, low: npt.NDArray[np.int64], high: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
        """Whether each span of registers ``low`` up to ``high`` (excluded; none where equal)
        carries part of a parameter over several registers, or a string."""
        top = LAYOUT_REGISTERS - 1  # a coil read names up to 2 000 (those frames' answer is not used)
        some = high > low
        low, high = np.clip(low, 0, top), np.clip(high, 0, top)
        last = np.maximum(high - 1, low)
        part: npt.NDArray[np.bool_] = some & (
            (self.word[low] > 0) | ((self.size[last] > 0) & (self.word[last] != self.size[last] - 1))
            | (self.texts[np.maximum(high, low)] > self.texts[low]))
        return part


def _wide_layout(profile: Profile) -> WideLayout:
    word, size = np.full(LAYOUT_REGISTERS, -1, np.int16), np.zeros(LAYOUT_REGISTERS, np.int16)
    text = np.zeros(LAYOUT_REGISTERS, np.int64)
    for address, (parameter, place) in profile.words_of.items():
        word[address], size[address] = place, parameter.registers
        text[address] = parameter.type == "string"
    return WideLayout(word, size, np.concatenate([[0], np.cumsum(text)]))


#: Registers a layout covers: every address, and those a read near the end names past it.
LAYOUT_REGISTERS = 0x10000 + 256
#: The layout of each profile with parameters over several registers, made once.
WIDE_LAYOUTS: KeptByIdentity[Profile, WideLayout] = KeptByIdentity(_wide_layout, most=64)


def overlap(low: npt.NDArray[np.int64], high: npt.NDArray[np.int64], first: int,
             count: int) -> npt.NDArray[np.bool_]:
    """Whether each span of registers ``low`` up to ``high`` (excluded) shares one with the
    ``count`` registers from ``first`` (a scanner table's)."""
    shared: npt.NDArray[np.bool_] = (low < first + count) & (high > first)
    return shared


