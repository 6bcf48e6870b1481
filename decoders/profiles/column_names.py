"""Profiles' names given to frames kept in columns, as array lookups.

Where a profile names a slave's registers, a frame's params are named values (code, name,
value, unit, and a text for the summary), each what the register's namer
(:class:`~decoders.profiles.naming.AddressNamer`) makes of its address and raw word. The frames
the annotator keeps in columns (:mod:`decoders.modbus.columnar`; which of a named slave's
frames may stay there: :mod:`decoders.profiles.columns`) get theirs at once here
(:func:`named`): every param of a named slave's frame is a key (its profile, whether the device
reported it, its address, its raw word, and at a scanner table's value register its slave,
whose own mapping names it), each distinct key of the batch is named once through the applier,
which keeps what its namers made as for any frame, and each param takes its entry
(:class:`~decoders.modbus.columnar.ColumnarNames`). A batch of drives polled for values that
change names a few thousand distinct values for tens of thousands of frames.

Frames that read alike (:func:`~decoders.modbus.alike.alike`: the same bytes, role, kind,
span and profile, so the same names) are named once, by the first of each group, and each
frame's params take their entries from it; the groups stay with the columns
(``ColumnarFrames.groups``), and writers spell each group's texts once by them. Measured on
1 M frames (thread time of ``export --parquet``'s main thread): steady traffic, where nearly
every frame repeats one polled before, 2.22 → 2.01 s; mixed traffic 2.95 → 2.86 s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from decoders.message import MessageBatch
from decoders.modbus.alike import alike
from decoders.modbus.codes import BIT_FUNCTIONS
from decoders.modbus.columnar import ColumnarFrames, ColumnarNames, one_of
from decoders.modbus.columnar_text import READ_ANSWER, WRITE_ANSWER
from decoders.profiles.apply import ProfileApplier
from decoders.profiles.columns import ColumnProfiles, FrameProfiles, overlap
from decoders.profiles.naming import NamedValue, NumberNames, PlainNumbers

#: Bits of a param's key (:func:`named`) for its raw word plus one (0: no value), its address (a
#: read's last register may lie past 65 535) and its slave plus one (0: a register whose name
#: no slave's mapping changes).
_RAW_BITS, _ADDRESS_BITS, _SLAVE_BITS = 17, 20, 9
_RAW_MASK, _ADDRESS_MASK, _SLAVE_MASK = (1 << _RAW_BITS) - 1, (1 << _ADDRESS_BITS) - 1, (1 << _SLAVE_BITS) - 1


def named(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames, framed: FrameProfiles, *,
          numbers: bool = False) -> ColumnarFrames:
    """``columnar`` with the names its frames' profiles give their params (none of them
    :func:`unnameable`); as it is where no frame's profile names anything. ``numbers``: values
    that are plain numbers are named in arrays (:class:`~decoders.profiles.naming.NumberNames`),
    for outputs that take them so; the others, and all without it, are named values.

    Frames that read alike (:func:`~decoders.modbus.alike.alike`: same bytes, kind, span and
    profile, hence the same names) are named once, by their group's first, and the groups kept
    in the result for writers to spell each group once: a bus polled for values that seldom
    change names a few frames of the batch instead of sorting all its params' values."""
    slaves = ColumnProfiles(framed, columnar.positions)
    if not _named_frames(columnar, slaves).any():
        return columnar
    profile = slaves.profile if framed.switched else None
    groups = alike(columnar, batch.frames.data, batch.frames.offsets, batch.role, profile)
    spelt = columnar if groups is None else columnar.take(groups.firsts)
    spelt_profiles = ColumnProfiles(framed, spelt.positions)
    row, table, number_names = _named_params(applier, batch, spelt, spelt_profiles, numbers=numbers)
    if groups is not None:  # each frame's params named as its group's first's
        row = row[columnar.grouped_params(groups)]
    return dataclasses.replace(columnar, names=ColumnarNames(row, table, number_names, profile), groups=groups)


def _named_params(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames, slaves: ColumnProfiles, *,
                  numbers: bool) -> tuple[npt.NDArray[np.int64], list[NamedValue], NumberNames | None]:
    """Each param's entry (``ColumnarNames.row``), the named values and the plain numbers of
    the frames of ``columnar`` (``slaves``: theirs)."""
    params = columnar.params(batch.frames.data)
    frame = np.repeat(np.arange(len(columnar)), params.sizes)
    rows = np.flatnonzero(_named_frames(columnar, slaves)[frame])
    of = frame[rows]
    reported = one_of(columnar.kind, (READ_ANSWER, WRITE_ANSWER))[of].astype(np.int64)
    address = params.address[rows]
    owner = _value_register_owners(slaves, of, address, batch.slave[columnar.positions].astype(np.int64))
    register = ((((slaves.profile[of] * 2 + reported) << _SLAVE_BITS) | owner) << _ADDRESS_BITS) | address
    distinct, inverse = np.unique((register << _RAW_BITS) | (params.value[rows] + 1), return_inverse=True)
    entry, table, number_names = _entries(applier, slaves, distinct, numbers=numbers)
    row = np.full(len(params.address), -1, np.int64)
    row[rows] = entry[inverse.reshape(-1)]
    return row, table, number_names


def _named_frames(columnar: ColumnarFrames, slaves: ColumnProfiles) -> npt.NDArray[np.bool_]:
    """Which frames of ``columnar`` (``slaves``: theirs) their profile names values of: a
    profile names registers, never coils."""
    named: npt.NDArray[np.bool_] = slaves.named & ~one_of(columnar.function, BIT_FUNCTIONS)
    return named


def _entries(applier: ProfileApplier, slaves: ColumnProfiles, distinct: npt.NDArray[np.int64], *,
             numbers: bool) -> tuple[npt.NDArray[np.int64], list[NamedValue], NumberNames | None]:
    """The entry of each distinct value (``distinct``: keys of :func:`named`, ascending), the
    named values (the first entries) and the plain numbers (the entries after them)."""
    registers, words = distinct >> _RAW_BITS, (distinct & _RAW_MASK) - 1
    starts = np.flatnonzero(np.diff(registers, prepend=-1))
    stops = np.append(starts[1:], len(distinct))
    named_at = []
    for key in registers[starts].tolist():
        group, slave = key >> (_ADDRESS_BITS + _SLAVE_BITS), ((key >> _ADDRESS_BITS) & _SLAVE_MASK) - 1
        named_at.append((slaves.profiles[group >> 1], slave, bool(group & 1), key & _ADDRESS_MASK))
    plains = [applier.plain_numbers(*register) for register in named_at] if numbers else []
    register_of = np.repeat(np.arange(len(starts)), stops - starts)
    as_number = _plain(plains, register_of, words)
    others = np.flatnonzero(~as_number)
    table: list[NamedValue] = []
    firsts, lasts = np.searchsorted(others, starts).tolist(), np.searchsorted(others, stops).tolist()
    for register, first, last in zip(named_at, firsts, lasts, strict=True):
        if last > first:
            raws = words[others[first:last]].tolist()
            table += applier.named_values(*register, [None if raw < 0 else raw for raw in raws])
    entry = np.empty(len(distinct), np.int64)
    entry[others] = np.arange(len(others))
    numbered = np.flatnonzero(as_number)
    entry[numbered] = np.arange(len(others), len(distinct))
    return entry, table, _number_names(plains, register_of[numbered], words[numbered])


def _plain(plains: list[PlainNumbers | None], register_of: npt.NDArray[np.int64],
           words: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """Which values (of registers ``register_of``, raw words ``words``) are plain numbers."""
    if not any(plains):
        return np.zeros(len(words), np.bool_)
    plain = np.array([found is not None for found in plains], np.bool_)[register_of] & (words >= 0)
    worded = [place * 0x10000 + found.words for place, found in enumerate(plains) if found is not None]
    return plain & ~np.isin(register_of * 0x10000 + words, np.concatenate(worded))


def _number_names(plains: list[PlainNumbers | None], register_of: npt.NDArray[np.int64],
                  raws: npt.NDArray[np.int64]) -> NumberNames | None:
    """The plain numbers (each of register ``register_of``, raw word in ``raws``) as columns."""
    if not len(raws):
        return None
    used, register = np.unique(register_of, return_inverse=True)
    # Every register a plain number lies in has its plain numbers.
    registers = [found for place in used.tolist() if (found := plains[place]) is not None]
    values = np.empty(len(raws), np.float64)
    tables: dict[int, list[int]] = {}  # registers by the table of values they share
    for place, found in enumerate(registers):
        tables.setdefault(id(found.value), []).append(place)
    for places in tables.values():
        of = np.isin(register, places)
        values[of] = registers[places[0]].value[raws[of]]
    return NumberNames(register.reshape(-1), raws, values, registers)


def _value_register_owners(slaves: ColumnProfiles, of: npt.NDArray[np.int64], address: npt.NDArray[np.int64],
                           frame_slaves: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """For each param (of frame ``of``, at ``address``): its slave plus one where it is a scanner
    table's value register (named by that slave's mapping), 0 elsewhere (named alike for all)."""
    owner = np.zeros(len(of), np.int64)
    for place, profile in enumerate(slaves.profiles):
        for table in profile.indirections:
            inside = (slaves.profile[of] == place) & overlap(address, address + 1, table.value_registers, table.count)
            owner[inside] = frame_slaves[of[inside]] + 1
    return owner
