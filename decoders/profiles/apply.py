"""Applies device profiles to decoded messages: names, units, scaled values, states, remarks.

One generic applier serves every profile; what differs between drives is data.
:class:`ProfileBook` says which profile speaks for which slave: one for all, one
per slave, and, when a slave identifies itself (FC 43 / MEI 14 product code), the
profile whose product codes match, from then on.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, cast

from decoders.message import Decoding, DeviceIdentity, ParamValue, Role
from decoders.modbus.codes import DATA_TABLE, REGISTERS
from decoders.modbus.param_runs import addressed_values
from decoders.modbus.pdu import (
    ExceptionPdu,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    WriteCoilsRequest,
    WriteRegistersRequest,
)
from decoders.modbus.pdu_serial import DeviceIdResponse
from decoders.profiles.book import ProfileBook
from decoders.profiles.model import Indirection, Profile
from decoders.profiles.naming import AddressNamer, NamedValue, summary_with

#: The slave column's value for a frame without a slave (noise).
NO_SLAVE = -1
KEPT_NAMED_PARAMS = 65536
PRODUCT_CODE_OBJECT = 1


class FrameFacts(NamedTuple):
    """What applying a profile reads of a frame besides its decoding (a tuple: one is built
    per frame decoded, and a frozen dataclass costs a setattr per field)."""

    slave: int | None
    role: Role
    function: int | None
    crc_ok: bool


@dataclass
class _Indirections:
    """Per slave and table: which parameter address each value register carries."""

    tables: dict[tuple[int, str], list[int]] = field(default_factory=dict)

    def mapping(self, slave: int, table: Indirection) -> list[int]:
        key = (slave, table.prefix)
        if key not in self.tables:
            self.tables[key] = list(table.defaults)
        return self.tables[key]


class ProfileApplier:
    """Adds profile knowledge to messages in capture order (it learns scanner tables).

    Namers and the values they named are kept between frames (the tests hold them to an
    applier that names every value anew, ``tests/oracles.py``).
    """

    def __init__(self, book: ProfileBook) -> None:
        self.book = book
        self._indirections = _Indirections()
        #: Counts what the applier has learnt (scanner tables, identified slaves): a decoding
        #: made at one version holds while the version stays.
        self.version = 0
        #: Namers by (profile, reported) and address (a scanner value register: (target, address)),
        #: for what they were at ``_named_version``; ``_kept``: how many namers and named values
        #: they hold.
        self._namers: dict[tuple[str, bool, int], dict[int | tuple[int | None, int], AddressNamer]] = {}
        self._named_version = 0
        self._kept = 0
        #: :func:`knows_nothing` of each slave's profile, while the version stays.
        self._adds_nothing: dict[int, bool] = {}
        self._adds_nothing_version = 0

    def adds_nothing(self, slave: int) -> bool:
        """Whether the profile in force for ``slave`` leaves a Modbus message as it is (a slave
        identifying itself aside: :meth:`apply` may then choose its profile)."""
        if self._adds_nothing_version != self.version:  # an identification may have changed a profile
            self._adds_nothing.clear()
            self._adds_nothing_version = self.version
        known = self._adds_nothing.get(slave)
        if known is None:
            known = self._adds_nothing[slave] = knows_nothing(self.book.profile_for(None if slave == NO_SLAVE
                                                                                      else slave))
        return known

    def apply_decoding(self, decoding: Decoding, facts: FrameFacts, request: Pdu | None) -> Decoding:
        """:meth:`apply` to a frame's decoding alone (``facts``: what it reads of the frame):
        the annotator's path, which builds no message for a frame it decodes."""
        slave = facts.slave
        if decoding.uss is not None:
            return _uss_words(self.book.profile_for(slave), decoding, facts.role)
        pdu = decoding.pdu
        device = self._identify(pdu, facts) if isinstance(pdu, DeviceIdResponse) else None
        if device is None and self.adds_nothing(NO_SLAVE if slave is None else slave):
            return decoding
        profile = self.book.profile_for(slave)
        table = DATA_TABLE.get(facts.function or 0, REGISTERS)
        # Coils and inputs a profile names none of keep their addresses (and the decoding).
        bits = table != REGISTERS and not profile.tables[table]
        params: Sequence[ParamValue] = decoding.params
        shown: list[str] = []
        remarks = list(decoding.remarks)
        if not bits:
            values = addressed_values(decoding)
            params, shown, parts, learns = self._named(profile, slave, facts.role is Role.RESPONSE, values, table)
            remarks += parts
            if learns:
                self._learn(profile, slave, values)
        if facts.role in (Role.REQUEST, Role.BROADCAST) and pdu is not None:
            remarks += limit_remarks(profile, facts, pdu)
        if isinstance(pdu, ExceptionPdu):
            remarks += _exception_remarks(profile, pdu, request)
        if device is not None:
            remarks.append(_device_remark(device))
        if bits and len(remarks) == len(decoding.remarks) and device is None:
            return decoding  # what the profile adds to it: nothing
        return Decoding(summary_with(decoding.summary, shown), tuple(params), pdu, tuple(remarks),
                        decoding.device if device is None else device, decoding.uss)

    def _named(self, profile: Profile, slave: int | None, reported: bool, values: list[tuple[int, int | None]],
               table: int = REGISTERS) -> tuple[list[ParamValue], list[str], list[str], bool]:
        """The params of ``values`` (of the data ``table``), the summary's texts of the named
        ones, the remarks on parameters named in part, and whether any is a scanner address
        register (``reported``: the values come from the device)."""
        found = self._address_namers(profile, slave, reported, [address for address, _ in values], table)
        raws = [raw for _, raw in values]
        if profile.words_of:
            params, shown, parts = self._name_wide_values(found, raws)
        else:
            (params, shown), parts = self._name_values(found, raws), []
        return params, shown, parts, any(namer.learns for namer in found)

    def named_values(self, profile: Profile, slave: int, reported: bool, address: int,
                     raws: list[int | None], *, table: int = REGISTERS) -> list[NamedValue]:
        """Each of ``raws`` at ``address`` (of the data ``table``) as :meth:`apply_decoding`
        names it for ``slave`` of ``profile`` (``reported``: the device's values) now, kept as
        there: for frames named in columns (:mod:`decoders.profiles.column_names`)."""
        namer = self._namer_of(profile, slave, reported, address, table)
        known, named = namer.known, []
        for raw in raws:
            value = known.get(raw)
            if value is None:
                value = namer.make(raw)
                self._kept += 1
            named.append(value)
        return named

    def named_words(self, profile: Profile, slave: int, reported: bool, address: int,
                    values: list[tuple[int | None, ...]]) -> list[NamedValue]:
        """Each of ``values`` of the parameter over several registers at ``address`` (all its
        registers' raw words, or ``None`` each) as :meth:`apply_decoding` names it, kept as
        there: for frames named in columns."""
        namer = self._namer_of(profile, slave, reported, address)
        known = namer.known
        found: list[NamedValue | None] = list(map(known.get, values))
        new = [place for place, named in enumerate(found) if named is None]
        if new:
            for place, named in zip(new, namer.make_values([values[place] for place in new]), strict=True):
                found[place] = named
            self._kept += len(new)
        return cast(list[NamedValue], found)

    def _namer_of(self, profile: Profile, slave: int, reported: bool, address: int,
                  table: int = REGISTERS) -> AddressNamer:
        namers = self._kept_namers(profile, reported, table)
        return namers.get(address) or self._namer_at(namers, profile, slave, address, reported, table=table)

    def _name_values(self, namers: list[AddressNamer],
                     raws: Sequence[int | None]) -> tuple[list[ParamValue], list[str]]:
        """Each raw value named by its namer (kept there): the params, and the summary's texts
        of those it shows."""
        params: list[ParamValue] = []
        shown: list[str] = []
        for namer, raw in zip(namers, raws, strict=True):
            named = namer.known.get(raw)
            if named is None:
                named = namer.make(raw)
                self._kept += 1
            params.append(named[0])
            if named[1] is not None:
                shown.append(named[1])
        return params, shown

    def _name_wide_values(self, namers: list[AddressNamer],
                          raws: list[int | None]) -> tuple[list[ParamValue], list[str], list[str]]:
        """:meth:`_name_values` where parameters take several registers: those a frame carries
        whole are one value, the others' registers named alone with a remark each."""
        params: list[ParamValue] = []
        shown: list[str] = []
        parts: list[str] = []
        at = 0
        while at < len(namers):
            namer, size = namers[at], namers[at].registers
            if size == 1:
                named = self._name_one(namer, raws[at])
            else:
                words = tuple(raws[at : at + size])
                whole = (namer.word == 0 and len(words) == size and all(
                    later.parameter is namer.parameter and later.word == word
                    for word, later in enumerate(namers[at : at + size]))
                    and (None not in words or words.count(None) == size))
                if whole:
                    named = namer.known.get(words) or self._kept_one(namer.make_values([words])[0])
                else:
                    named = namer.known.get(raws[at]) or self._kept_one(namer.make_part(raws[at]))
                    remark = namer.part_remark()
                    if remark is not None:
                        parts.append(remark)
                    size = 1
            params.append(named[0])
            if named[1] is not None:
                shown.append(named[1])
            at += size
        return params, shown, parts

    def _name_one(self, namer: AddressNamer, raw: int | None) -> NamedValue:
        named = namer.known.get(raw)
        return named if named is not None else self._kept_one(namer.make(raw))

    def _kept_one(self, named: NamedValue) -> NamedValue:
        self._kept += 1
        return named

    def _kept_namers(self, profile: Profile, reported: bool,
                     table: int = REGISTERS) -> dict[int | tuple[int | None, int], AddressNamer]:
        """The namers kept for ``profile``'s values (``reported``: from the device), all let go
        first when the profiles learnt something or the kept values reached their bound."""
        if self._named_version != self.version or self._kept >= KEPT_NAMED_PARAMS:
            self._namers.clear()
            self._named_version, self._kept = self.version, 0
        # Slaves share a profile's namers (a value's name says nothing of its slave), and at a
        # scanner table's value registers, whose meaning is each slave's own mapping's, those
        # mapped alike (kept by target and address there: _namer_at).
        key = (profile.id, reported, table)
        namers = self._namers.get(key)
        if namers is None:
            namers = self._namers[key] = {}
        return namers

    def _address_namers(self, profile: Profile, slave: int | None, reported: bool,
                        addresses: list[int], table: int = REGISTERS) -> list[AddressNamer]:
        """The kept namer of each of ``addresses`` (made and kept where new)."""
        namers = self._kept_namers(profile, reported, table)
        return [namers.get(address) or self._namer_at(namers, profile, slave, address, reported, table=table)
                for address in addresses]

    def _namer_at(self, namers: dict[int | tuple[int | None, int], AddressNamer], profile: Profile,
                  slave: int | None, address: int, reported: bool, *, table: int = REGISTERS) -> AddressNamer:
        """The namer of ``address`` among ``namers`` (made and kept there if new). A scanner
        table's value register holds what its slave's mapping points it at: kept by that target
        (``None``: no slave), so that slaves mapped alike share its namer and the values it made
        (16 drives polled by one PLC: their scanners are mapped alike, factory-set)."""
        if table != REGISTERS:  # a coil or input: no scanner maps them
            bit = namers[address] = AddressNamer.of_bit(profile, address, profile.tables[table].get(address))
            self._kept += 1
            return bit
        scanner = _value_table(profile, address)
        key: int | tuple[int | None, int] = address
        if scanner is not None:
            slot = address - scanner.value_registers
            key = (None if slave is None else self._indirections.mapping(slave, scanner)[slot], address)
        found = namers.get(key)
        if found is None:
            found = namers[key] = self._namer(profile, slave, address, reported)
            self._kept += 1
        return found

    def _namer(self, profile: Profile, slave: int | None, address: int, reported: bool) -> AddressNamer:
        """How ``profile`` names the register at ``address`` of ``slave`` now (the rules:
        :mod:`decoders.profiles.naming`)."""
        learns = any(0 <= address - table.address_registers < table.count for table in profile.indirections)
        parameter, word = profile.words_of.get(address) or (profile.parameters.get(address), 0)
        # A parameter without a code (``--registers``: a type, no name) names nothing.
        label: tuple[str | None, str | None] = (
            (parameter.code or None, parameter.name or None) if parameter is not None
            else (f"%MW{address}", f"4{address + 1:05d}") if profile.address_style == "xbt" else (None, None))
        table = _value_table(profile, address)
        if slave is not None and table is not None:
            slot = address - table.value_registers
            target = self._indirections.mapping(slave, table)[slot]
            code = f"{table.prefix}{slot + 1}"
            parameter, word = profile.parameters.get(target) if target else None, 0
            if parameter is not None and parameter.registers > 1:  # a copy of one register: no wider value
                parameter = None
            if parameter is None:
                what = "unassigned" if not target else f"copy of register {target}"
                label = (code, f"{code} ({what})")
            else:
                label = (f"{code}→{parameter.code}", f"{code} → {parameter.name}")
        return AddressNamer(profile, address, label, parameter, reported=reported, learns=learns, word=word)

    def _identify(self, pdu: DeviceIdResponse, facts: FrameFacts) -> DeviceIdentity | None:
        slave = facts.slave
        if slave is None or not facts.crc_ok:
            return None
        objects = identity_objects(pdu)
        product = objects.get(PRODUCT_CODE_OBJECT)
        if product is None:
            return None
        before = self.book.profile_for(slave)
        profile = self.book.identify(slave, product)
        if self.book.profile_for(slave) is not before:
            self.version += 1
        return DeviceIdentity(
            slave=slave,
            vendor=objects.get(0),
            product_code=product,
            revision=objects.get(2),
            profile=profile.id if profile is not None else None,
            applied=profile is not None and self.book.profile_for(slave) is profile,
        )

    def would_learn(self, profile: Profile, slave: int, values: list[tuple[int, int | None]]) -> bool:
        """Whether a frame of ``slave`` (named by ``profile``) carrying ``values`` (address and raw
        word) would change its scanner tables as :meth:`_learn` does; nothing is learnt here."""
        tables = self._indirections.tables
        return any(tables.get((slave, table.prefix), table.defaults)[slot] != raw
                   for table, slot, raw in _address_slots(profile, values))

    def _learn(self, profile: Profile, slave: int | None, values: list[tuple[int, int | None]]) -> None:
        """Scanner address registers seen being read or written change the table."""
        if slave is None:
            return
        for table, slot, raw in _address_slots(profile, values):
            mapping = self._indirections.mapping(slave, table)
            if mapping[slot] != raw:
                mapping[slot] = raw
                self.version += 1


def _address_slots(profile: Profile, values: list[tuple[int, int | None]]) -> Iterator[tuple[Indirection, int, int]]:
    """Each of ``values`` (address and raw word) that sets an address register of one of
    ``profile``'s scanner tables: the table, the register's slot in it, the address it holds."""
    for table in profile.indirections:
        for address, raw in values:
            slot = address - table.address_registers
            if 0 <= slot < table.count and raw is not None:
                yield table, slot, raw


def identity_objects(pdu: DeviceIdResponse) -> dict[int, str]:
    """The objects an identification answer gives, by id (the last, where it gives one twice)."""
    return {found.object_id: found.text for found in pdu.objects}


def product_code(pdu: DeviceIdResponse) -> str | None:
    """The product code an identification answer gives, if it gives one."""
    return identity_objects(pdu).get(PRODUCT_CODE_OBJECT)


def _uss_words(profile: Profile, decoding: Decoding, role: Role) -> Decoding:
    """The first process-data word read as the control word (master) or status word (drive)."""
    telegram = decoding.uss
    assert telegram is not None
    name = profile.uss_control_word if role is Role.REQUEST else profile.uss_status_word
    if name is None or not telegram.pzd:
        return decoding
    word = telegram.pzd[0]
    label = "STW" if role is Role.REQUEST else "ZSW"
    described = profile.bitfields[name].describe(word)
    return Decoding(f"{decoding.summary}: {label} = 16#{word:04X} {described}", decoding.params, decoding.pdu,
                    decoding.remarks, decoding.device, telegram)


def _value_table(profile: Profile, address: int) -> Indirection | None:
    """The scanner table whose value registers hold ``address``, if any: what such a register
    holds depends on the slave (its own mapping)."""
    return next((table for table in profile.indirections if 0 <= address - table.value_registers < table.count),
                None)


def knows_nothing(profile: Profile) -> bool:
    """A profile with nothing to add (generic): messages pass unchanged."""
    return not (profile.parameters or profile.coils or profile.inputs or profile.specials or profile.indirections
                or profile.exceptions
                or profile.limits.functions or profile.address_style != "plain" or profile.uss_control_word)


def limit_remarks(profile: Profile, facts: FrameFacts, pdu: Pdu) -> list[str]:
    """What ``profile`` remarks of a request: a function it does not support, counts past its limits."""
    limits, name, function = profile.limits, profile.name, facts.function
    remarks = []
    if limits.functions and function not in limits.functions:
        remarks.append(f"{name} does not support function {function} (expect exception 01)")
    if facts.role is Role.BROADCAST and limits.broadcast_functions and function not in limits.broadcast_functions:
        allowed = ", ".join(str(f) for f in limits.broadcast_functions)
        remarks.append(f"{name} takes broadcasts only for functions {allowed}")
    checks: list[tuple[int, int, str]] = []
    if isinstance(pdu, ReadRequest) and pdu.function in (3, 4):
        checks.append((pdu.count, limits.read_registers, "reads"))
    if isinstance(pdu, WriteRegistersRequest | WriteCoilsRequest):
        checks.append((pdu.count, limits.write_registers, "writes"))
    if isinstance(pdu, ReadWriteRequest):
        checks += [(pdu.read_count, limits.read_write_read, "reads (FC 23)"),
                   (pdu.write_count, limits.read_write_write, "writes (FC 23)")]
    for count, limit, verb in checks:
        if limit and count > limit:
            remarks.append(f"{verb} {count} words; {name} {verb.split()[0]} at most {limit}")
    return remarks


def _exception_remarks(profile: Profile, pdu: ExceptionPdu, request: Pdu | None) -> list[str]:
    asked = set(request_addresses(request))
    return [
        note.explanation
        for note in profile.exceptions
        if note.code == pdu.code
        and note.function in (0, pdu.function)
        and (not note.addresses or asked & set(note.addresses))
    ]


def request_addresses(pdu: Pdu | None) -> list[int]:
    """The registers or coils a request names (its read and its written ones)."""
    if isinstance(pdu, ReadRequest | WriteRegistersRequest | WriteCoilsRequest):
        return list(range(pdu.address, pdu.address + pdu.count))
    if isinstance(pdu, ReadWriteRequest):
        return [*range(pdu.read_address, pdu.read_address + pdu.read_count),
                *range(pdu.write_address, pdu.write_address + pdu.write_count)]
    address = getattr(pdu, "address", None)
    return [address] if isinstance(address, int) else []


def _device_remark(device: DeviceIdentity) -> str:
    if device.profile is None:
        return f"slave {device.slave} is {device.product_code}: no known profile matches"
    if device.applied:
        return f"slave {device.slave} is {device.product_code}: decoded with profile {device.profile}"
    return f"slave {device.slave} is {device.product_code}: matches profile {device.profile} (another was chosen)"
