"""Profiles applied as array lookups: frames of named slaves kept in columns.

Where a profile names a slave's registers, a frame's params are named values (code, name,
value, unit, and a text for the summary), each what the register's namer
(:class:`~decoders.profiles.naming.AddressNamer`) makes of its address and raw word. The frames
the annotator keeps in columns (:mod:`decoders.modbus.columnar`) get theirs at once here
(:func:`named`): every param of a named slave's frame is a key (its profile, whether the device
reported it, its address, its raw word), each distinct key of the batch is named once through
the applier, which keeps what its namers made as for any frame, and each param takes its entry
(:class:`~decoders.modbus.columnar.ColumnarNames`). A batch of drives polled for values that
change names a few thousand distinct values for tens of thousands of frames.

A named slave's frame stays in columns only where naming it is that lookup alone, all that
:meth:`~decoders.profiles.apply.ProfileApplier.apply_decoding` would do to it:

* none of its registers is in a scanner table (:func:`unnameable`): an address register teaches
  the table, and a value register's name is its own slave's mapping at that frame;
* a request the profile remarks nothing of (:func:`unnameable`: a function it supports, counts
  within its limits; answers in columns are never exceptions, which may get remarks);
* its profile names no two registers alike and names none by a number (:func:`plain_codes`):
  the MCAP params message holds a frame's values by code, or by address where none names it;
* not from its slave's identification on (FC 43 may give the slave another profile: the
  annotator's rule).

The annotator leaves the frames :func:`unnameable` finds out and finds the columns again. The
tests hold every output of frames so named to the plain path (``tests/property/test_columnar.py``,
``tests/property/test_columnar_parts.py``, ``tests/test_columnar_outputs.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from decoders.message import MessageBatch, Role
from decoders.modbus.columnar import ColumnarFrames, ColumnarNames
from decoders.modbus.columnar_text import READ, READ_ANSWER, WRITE, WRITE_ANSWER
from decoders.modbus.pdu_parse import parse_pdu
from decoders.profiles.apply import FrameFacts, ProfileApplier, limit_remarks
from decoders.profiles.model import Profile

#: Bits of a param's key (:func:`named`) for its raw word plus one (0: no value) and its address
#: (a read's last register may lie past 65 535).
_RAW_BITS, _ADDRESS_BITS = 17, 20
_RAW_MASK, _ADDRESS_MASK = (1 << _RAW_BITS) - 1, (1 << _ADDRESS_BITS) - 1


def plain_codes(profile: Profile) -> bool:
    """Whether ``profile`` names each register by a code of its own that is not a number (a
    frame's values, keyed by code or else by address, then never share a key)."""
    codes = [parameter.code for parameter in profile.parameters.values()]
    return len(set(codes)) == len(codes) and not any(code.isdigit() for code in codes)


class _Slaves:
    """The profile in force for the slave of each frame kept in columns (``profile``: its
    place in ``profiles``), and whether it names anything (``named``)."""

    def __init__(self, applier: ProfileApplier, slaves: npt.NDArray[np.int64]) -> None:
        distinct, at = np.unique(slaves, return_inverse=True)
        self.profiles: list[Profile] = []
        places: dict[int, int] = {}
        profile_of, names = [], []
        for slave in distinct.tolist():
            profile = applier.book.profile_for(slave)
            profile_of.append(places.setdefault(id(profile), len(places)))
            if len(places) > len(self.profiles):
                self.profiles.append(profile)
            names.append(not applier.adds_nothing(slave))
        self.profile: npt.NDArray[np.int64] = np.array(profile_of, np.int64)[at]
        self.named: npt.NDArray[np.bool_] = np.array(names, np.bool_)[at]


def unnameable(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames) -> npt.NDArray[np.int64]:
    """The positions of the frames of ``columnar`` (found in ``batch``) whose naming is more
    than a lookup: a scanner table's register, or a request the profile remarks on."""
    slaves = _Slaves(applier, batch.slave[columnar.positions].astype(np.int64))
    bad = np.zeros(len(columnar), np.bool_)
    if not slaves.named.any():
        return columnar.positions[bad]
    low = columnar.address
    high = low + np.maximum(columnar.count, 0)
    for place, profile in enumerate(slaves.profiles):
        of = slaves.named & (slaves.profile == place)
        for table in profile.indirections:
            for first in (table.address_registers, table.value_registers):
                bad |= of & (low < first + table.count) & (high > first)
    requests = np.flatnonzero(slaves.named & np.isin(columnar.kind, (READ, WRITE)) & ~bad)
    if len(requests):
        # A request's remarks depend on its profile, function and count alone: one of each asked.
        key = (slaves.profile[requests] << 32) | (columnar.function[requests] << 16) | columnar.count[requests]
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
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


def named(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames) -> ColumnarFrames:
    """``columnar`` with the names its frames' profiles give their params (none of them
    :func:`unnameable`); as it is where no frame's profile names anything."""
    slaves = _Slaves(applier, batch.slave[columnar.positions].astype(np.int64))
    if not slaves.named.any():
        return columnar
    params = columnar.params(batch.frames.data)
    frame = np.repeat(np.arange(len(columnar)), params.sizes)
    rows = np.flatnonzero(slaves.named[frame])
    of = frame[rows]
    reported = np.isin(columnar.kind, (READ_ANSWER, WRITE_ANSWER))[of].astype(np.int64)
    register = ((slaves.profile[of] * 2 + reported) << _ADDRESS_BITS) | params.address[rows]
    distinct, inverse = np.unique((register << _RAW_BITS) | (params.value[rows] + 1), return_inverse=True)
    registers = distinct >> _RAW_BITS
    cuts = (np.flatnonzero(np.diff(registers)) + 1).tolist()
    table = []
    for start, stop in zip([0, *cuts], [*cuts, len(distinct)], strict=True):
        group, address = int(registers[start]) >> _ADDRESS_BITS, int(registers[start]) & _ADDRESS_MASK
        raws = [None if raw < 0 else raw for raw in ((distinct[start:stop] & _RAW_MASK) - 1).tolist()]
        table += applier.named_values(slaves.profiles[group >> 1], bool(group & 1), address, raws)
    row = np.full(len(params.address), -1, np.int64)
    row[rows] = inverse.reshape(-1)
    return dataclasses.replace(columnar, names=ColumnarNames(row, table))
