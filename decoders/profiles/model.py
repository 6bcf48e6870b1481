"""Device profiles: what a drive's registers mean, as typed data loaded from TOML.

A profile is data, not code: :mod:`decoders.profiles.loader` reads any file of
this shape and :mod:`decoders.profiles.apply` applies any profile. The format is
documented in docs/profiles.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class Bit:
    """One bit of a bit-field word; ``set``/``clear`` name the state when it is 1 / 0."""

    bit: int
    name: str
    set: str | None = None
    clear: str | None = None


@dataclass(frozen=True, slots=True)
class State:
    """A state of a state machine, recognised by ``word & mask == value``."""

    mask: int
    value: int
    name: str


@dataclass(frozen=True, slots=True)
class BitField:
    """The meaning of a status or control word: bits, and the state its bits encode."""

    id: str
    source: str
    bits: tuple[Bit, ...] = ()
    states: tuple[State, ...] = ()

    def state(self, word: int) -> str | None:
        for state in self.states:
            if word & state.mask == state.value:
                return state.name
        return None

    def describe(self, word: int) -> str:
        """The state, then the named conditions of the bits that carry ``set``/``clear`` texts."""
        parts = [name] if (name := self.state(word)) else []
        for bit in self.bits:
            text = bit.set if word >> bit.bit & 1 else bit.clear
            if text:
                parts.append(text)
        return ", ".join(parts)


@dataclass(frozen=True, slots=True)
class Parameter:
    """One register: where it is, what it is called, how its raw value reads."""

    address: int
    code: str
    name: str
    source: str
    unit: str | None = None
    scale: float = 1.0
    signed: bool = False
    access: str = "rw"
    enum: dict[int, str] = field(default_factory=dict)
    bitfield: str | None = None
    note: str | None = None
    #: How its registers read (:mod:`decoders.value_types`): ``u16`` (``i16`` where ``signed``),
    #: or a type over ``registers`` registers in ``word_order``.
    type: str = "u16"
    registers: int = 1
    word_order: str = "big"


@dataclass(frozen=True, slots=True)
class Special:
    """A raw value that means something other than a number (e.g. 16#8000)."""

    raw: int
    meaning: str
    source: str


@dataclass(frozen=True, slots=True)
class ExceptionNote:
    """What an exception means on this device, for a function (0: any) and addresses."""

    code: int
    explanation: str
    source: str
    function: int = 0
    addresses: tuple[int, ...] = ()


@dataclass(frozen=True, slots=True)
class Limits:
    """What the device accepts; 0 means "no limit known"."""

    functions: tuple[int, ...] = ()
    broadcast_functions: tuple[int, ...] = ()
    read_registers: int = 0
    write_registers: int = 0
    read_write_read: int = 0
    read_write_write: int = 0


@dataclass(frozen=True, slots=True)
class Indirection:
    """A table of value registers whose meaning is set by address registers (the Altivar
    communication scanner: NMx holds a copy of the parameter whose address NMAx holds)."""

    prefix: str
    address_registers: int
    value_registers: int
    count: int
    defaults: tuple[int, ...]
    source: str


@dataclass(frozen=True, slots=True)
class Profile:
    """Everything known about one kind of device."""

    id: str
    name: str
    role: str
    sources: tuple[str, ...]
    parameters: dict[int, Parameter]
    bitfields: dict[str, BitField] = field(default_factory=dict)
    specials: tuple[Special, ...] = ()
    exceptions: tuple[ExceptionNote, ...] = ()
    limits: Limits = field(default_factory=Limits)
    indirections: tuple[Indirection, ...] = ()
    product_codes: tuple[str, ...] = ()
    address_style: str = "plain"
    notes: tuple[str, ...] = ()
    #: Bit fields of the first USS process-data word: control word (master) and status word (drive).
    uss_control_word: str | None = None
    uss_status_word: str | None = None
    path: str = ""
    #: Coils (FC 1, 5, 15) and discrete inputs (FC 2) it names, by address: ``type`` ``bool``.
    coils: dict[int, Parameter] = field(default_factory=dict)
    inputs: dict[int, Parameter] = field(default_factory=dict)
    #: :attr:`specials` by raw word (the first of each): looked up for every value a drive reports.
    special_meanings: dict[int, str] = field(init=False, repr=False, compare=False)
    #: Its parameters, coils and inputs, by the data table's number (:data:`~decoders.modbus.codes.DATA_TABLE`).
    tables: tuple[dict[int, Parameter], ...] = field(init=False, repr=False, compare=False)
    #: Every register of a parameter over more than one: its parameter and place in it.
    words_of: dict[int, tuple[Parameter, int]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "special_meanings", {s.raw: s.meaning for s in reversed(self.specials)})
        object.__setattr__(self, "tables", (self.parameters, self.coils, self.inputs))
        object.__setattr__(self, "words_of", {
            parameter.address + word: (parameter, word) for parameter in self.parameters.values()
            if parameter.registers > 1 for word in range(parameter.registers)})

