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
(:class:`~decoders.modbus.columnar.ColumnarNames`). A parameter over several registers (a
float) is keyed by its register and all its words, its distinct values read at once; its later
registers are :data:`~decoders.modbus.columnar.PART_OF_VALUE`. A batch of drives polled for values that
change names a few thousand distinct values for tens of thousands of frames.

Frames that read alike (:func:`~decoders.modbus.alike.alike`: the same bytes, role, kind and
span, so the same names: a part of a batch names each slave by one profile) are named once, by
the first of each group, and each frame's params take their entries from it; the groups stay with the columns
(``ColumnarFrames.groups``), and writers spell each group's texts once by them: where nearly
every frame repeats one polled before, few frames are named.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from decoders.message import MessageBatch
from decoders.modbus.alike import alike
from decoders.modbus.codes import DATA_TABLE
from decoders.modbus.columnar import PART_OF_VALUE, ColumnarFrames, ColumnarNames, one_of
from decoders.modbus.columnar_text import READ_ANSWER, WRITE_ANSWER
from decoders.profiles.apply import ProfileApplier
from decoders.profiles.columns import WIDE_LAYOUTS, ColumnProfiles, FrameProfiles, overlap
from decoders.profiles.model import Profile
from decoders.profiles.naming import NamedValue

#: Bits of a param's key (:func:`named`) for its raw word plus one (0: no value), its address (a
#: read's last register may lie past 65 535) and its slave plus one (0: a register whose name
#: no slave's mapping changes).
_RAW_BITS, _ADDRESS_BITS, _SLAVE_BITS = 17, 20, 9
_RAW_MASK, _ADDRESS_MASK, _SLAVE_MASK = (1 << _RAW_BITS) - 1, (1 << _ADDRESS_BITS) - 1, (1 << _SLAVE_BITS) - 1
#: The data tables a profile names (registers, coils, inputs), and each function's.
_TABLES = 3
DATA_TABLES = np.zeros(257, np.int64)
for _function, _table in DATA_TABLE.items():
    DATA_TABLES[_function] = _table


def named(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames,
          framed: FrameProfiles) -> ColumnarFrames:
    """``columnar`` with the names its frames' profiles give their params (none of them
    :func:`unnameable`); as it is where no frame's profile names anything.

    Frames that read alike (:func:`~decoders.modbus.alike.alike`: same bytes, kind and span,
    hence the same names) are named once, by their group's first, and the groups kept
    in the result for writers to spell each group once: a bus polled for values that seldom
    change names a few frames of the batch instead of sorting all its params' values."""
    slaves = ColumnProfiles(framed, columnar.positions)
    if not _named_frames(columnar, slaves).any():
        return columnar
    groups = alike(columnar, batch.frames.data, batch.frames.offsets, batch.role)
    spelt = columnar if groups is None else columnar.take(groups.firsts)
    spelt_profiles = ColumnProfiles(framed, spelt.positions)
    row, table = _named_params(applier, batch, spelt, spelt_profiles)
    if groups is not None:  # each frame's params named as its group's first's
        row = row[columnar.grouped_params(groups)]
    return dataclasses.replace(columnar, names=ColumnarNames(row, table), groups=groups)


def _named_params(applier: ProfileApplier, batch: MessageBatch, columnar: ColumnarFrames,
                  slaves: ColumnProfiles) -> tuple[npt.NDArray[np.int64], list[NamedValue]]:
    """Each param's entry (``ColumnarNames.row``) and the named values of the frames of
    ``columnar`` (``slaves``: theirs). A parameter over several registers (every frame here
    carries all of its registers or none: :func:`~decoders.profiles.columns.unnameable`) is
    an entry at its first register, keyed by all its words; its other registers are
    :data:`~decoders.modbus.columnar.PART_OF_VALUE`."""
    params = columnar.params(batch.frames.data)
    frame = np.repeat(np.arange(len(columnar)), params.sizes)
    rows = np.flatnonzero(_named_frames(columnar, slaves)[frame])
    of = frame[rows]
    reported = one_of(columnar.kind, (READ_ANSWER, WRITE_ANSWER))[of].astype(np.int64)
    address = params.address[rows]
    owner = _value_register_owners(slaves, of, address, batch.slave[columnar.positions].astype(np.int64))
    data_table = DATA_TABLES[columnar.function[of]]  # registers, coils or inputs
    group = (slaves.profile[of] * _TABLES + data_table) * 2 + reported
    register = (((group << _SLAVE_BITS) | owner) << _ADDRESS_BITS) | address
    value = params.value[rows]
    row = np.full(len(params.address), -1, np.int64)
    word, size = _wide_places(slaves, of, address)
    if word is None or size is None:
        distinct, inverse = np.unique((register << _RAW_BITS) | (value + 1), return_inverse=True)
        row[rows] = inverse.reshape(-1)  # each distinct value is an entry of the table, in order
        return row, _named_table(applier, slaves, distinct)
    first, single = (word == 0) & (size > 1), word < 0
    distinct, inverse = np.unique((register[single] << _RAW_BITS) | (value[single] + 1), return_inverse=True)
    row[rows[single]] = inverse.reshape(-1)
    table = _named_table(applier, slaves, distinct)
    starts = np.flatnonzero(first)
    registers, words, inverse = _distinct_values(register[starts], value, starts, size[starts])
    row[rows[starts]] = len(table) + inverse
    row[rows[word > 0]] = PART_OF_VALUE
    return row, table + _named_words(applier, slaves, registers, words)


def _distinct_values(register: npt.NDArray[np.int64], value: npt.NDArray[np.int64], starts: npt.NDArray[np.int64],
                     size: npt.NDArray[np.int16]) -> tuple[npt.NDArray[np.int64], list[tuple[int | None, ...]],
                                                            npt.NDArray[np.int64]]:
    """The distinct values over several registers among those whose first register is at
    ``starts`` of ``value`` (``register``: its key; ``size``: its registers, the next of
    ``value`` in turn): each one's register key (ascending) and words (``None`` each where a
    request names them), and each value's place among them. By a sort of the register and the
    words as one number (64 bits hold an ``f64``'s four), not a sort of rows."""
    combined = np.zeros(len(starts), np.uint64)
    for place in range(int(size.max(initial=0))):
        inside = np.flatnonzero(place < size)
        combined[inside] = (combined[inside] << np.uint64(16)) | (value[starts[inside] + place] & 0xFFFF).astype(
            np.uint64)
    asked = value[starts] < 0  # a request: no words
    order = np.lexsort((combined, asked, register))
    new = np.ones(len(order), np.bool_)
    for column in (register, asked, combined):
        ordered = column[order]
        new[1:] &= ordered[1:] == ordered[:-1]
    new = ~new
    new[:1] = True
    inverse = np.empty(len(order), np.int64)
    inverse[order] = np.cumsum(new) - 1
    firsts = order[new]
    counts = np.unique(size[firsts]).tolist()
    words: list[tuple[int | None, ...]] = [()] * len(firsts)
    for count in counts:
        pick = np.flatnonzero(size[firsts] == count)
        at = starts[firsts[pick]]
        found: list[tuple[int | None, ...]] = list(zip(*[value[at + place].tolist() for place in range(count)],
                                                       strict=True))
        if len(counts) == 1:  # one size (a bus of floats): the words in order as they are
            words = found
        else:
            for place, carried in zip(pick.tolist(), found, strict=True):
                words[place] = carried
    for place in np.flatnonzero(asked[firsts]).tolist():  # a request's value: no words
        words[place] = (None,) * len(words[place])
    return register[firsts], words, inverse


def _wide_places(slaves: ColumnProfiles, of: npt.NDArray[np.int64], address: npt.NDArray[np.int64]) -> tuple[
        npt.NDArray[np.int16] | None, npt.NDArray[np.int16] | None]:
    """Each param's place in its parameter over several registers (-1: none) and that
    parameter's size; ``None`` where no profile has one."""
    word = size = None
    for place, profile in enumerate(slaves.profiles):
        if profile.words_of:
            if word is None or size is None:
                word, size = np.full(len(of), -1, np.int16), np.zeros(len(of), np.int16)
            inside = np.flatnonzero(slaves.profile[of] == place)
            word[inside], size[inside] = WIDE_LAYOUTS.of(profile).at(address[inside])
    return word, size


def _named_words(applier: ProfileApplier, slaves: ColumnProfiles, registers: npt.NDArray[np.int64],
                 words: list[tuple[int | None, ...]]) -> list[NamedValue]:
    """Each distinct value over several registers named (``registers``: its register's key as
    :func:`_named_params` makes it, ascending; ``words``: its words), in their order: register
    after register, a register's values by the applier at once."""
    named: list[NamedValue] = []
    for register, _, first, last in _by_register(slaves, registers):
        named += applier.named_words(*register, words[first:last])
    return named


def _by_register(slaves: ColumnProfiles, registers: npt.NDArray[np.int64]) -> Iterator[tuple[
        tuple[Profile, int, bool, int], int, int, int]]:
    """Each register among ``registers`` (keys as :func:`_named_params` makes them, ascending):
    its profile, slave, whether reported and address, its data table, and where its run of
    keys begins and ends."""
    if not len(registers):
        return
    starts = np.flatnonzero(np.diff(registers, prepend=-1))
    stops = np.append(starts[1:], len(registers))
    for key, first, last in zip(registers[starts].tolist(), starts.tolist(), stops.tolist(), strict=True):
        group, slave = key >> (_ADDRESS_BITS + _SLAVE_BITS), ((key >> _ADDRESS_BITS) & _SLAVE_MASK) - 1
        register = (slaves.profiles[group // (2 * _TABLES)], slave, bool(group & 1), key & _ADDRESS_MASK)
        yield register, (group >> 1) % _TABLES, first, last


def _named_frames(columnar: ColumnarFrames, slaves: ColumnProfiles) -> npt.NDArray[np.bool_]:
    """Which frames of ``columnar`` (``slaves``: theirs) their profile names values of: its
    registers, and its coils or inputs where it names any of that table."""
    # A profile that adds anything names registers (by its parameters, its address style).
    names_table = np.array([[True, bool(profile.coils), bool(profile.inputs)] for profile in slaves.profiles],
                           np.bool_).reshape(len(slaves.profiles), _TABLES)
    named: npt.NDArray[np.bool_] = slaves.named & names_table[slaves.profile, DATA_TABLES[columnar.function]]
    return named


def _named_table(applier: ProfileApplier, slaves: ColumnProfiles, distinct: npt.NDArray[np.int64]) -> list[NamedValue]:
    """Each distinct value named (``distinct``: keys of :func:`named`, ascending), in their order:
    register after register, a register's raw words by the applier at once."""
    raws = ((distinct & _RAW_MASK) - 1).tolist()
    table: list[NamedValue] = []
    for register, data_table, first, last in _by_register(slaves, distinct >> _RAW_BITS):
        table += applier.named_values(*register, [None if raw < 0 else raw for raw in raws[first:last]],
                                      table=data_table)
    return table


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
