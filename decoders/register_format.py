"""A frame's registers and addresses in the table as a device's manual writes them, for devices
without a profile (``--registers``, ``--addressing``).

* **Values**: the values of the frame's params, as the decoding made them: ``--registers``
  types registers by the profile it makes (:func:`sniffer.profiles_io.registers_profile`,
  read by :mod:`decoders.value_types`: ``u32`` two registers at a time, ``f32`` a float, …),
  and a register left over, part of a value the frame does not carry whole, is written as its
  word after a ``+``. With ``hex`` (or ``--addressing`` alone): the words in hexadecimal.
* **Addresses** (``addressing``): ``wire`` (the number sent, from 0), ``1`` (from 1, as most
  manuals number registers) or ``4x`` (the Modicon reference: 40001 + wire for holding
  registers, 30001 for input registers, 00001 for coils, 10001 for discrete inputs).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from decoders.message import ParamValue
from decoders.modbus.codes import REFERENCE_BASE, TABLE_NAMES
from decoders.modbus.pdu import (
    COIL_ON,
    Pdu,
    ReadRequest,
    ReadWriteRequest,
    RegistersResponse,
    WriteMultipleResponse,
    WriteRegistersRequest,
    WriteSingle,
)
from decoders.value_types import ORDERS, TYPES

#: The names ``--registers`` takes: ``s16``/``s32`` as earlier versions named ``i16``/``i32``.
ALIASES = {"s16": "i16", "s32": "i32"}
KINDS = ("hex", *[name for name in TYPES if name != "string"], *ALIASES)
WORD_ORDERS = ORDERS
ADDRESSINGS = ("wire", "1", "4x")
#: Values written out before "… (+N registers)".
SHOWN_VALUES = 16


@dataclass(frozen=True)
class RegisterFormat:
    """``typed``: write the params' values (else their words in hex)."""

    typed: bool = False
    addressing: str = "wire"

    def __post_init__(self) -> None:
        if self.addressing not in ADDRESSINGS:
            raise ValueError(f"addressing {self.addressing!r} is not one of {ADDRESSINGS}")

    def address(self, function: int, wire: int) -> str:
        """One address as this addressing writes it."""
        if self.addressing == "wire":
            return str(wire)
        if self.addressing == "1":
            return str(wire + 1)
        base = REFERENCE_BASE.get(function, 40001)
        return f"{base + wire:05d}" if base + wire < 100000 else f"{base // 10000}{wire + 1:05d}"

    def span(self, function: int, wire: int, count: int) -> str:
        first = self.address(function, wire)
        return first if count == 1 else f"{first}..{self.address(function, wire + count - 1)}"

    def values(self, params: Sequence[ParamValue]) -> str:
        """The values of ``params`` (those that carry one), space separated."""
        carried = [param for param in params if param.raw is not None or param.words is not None]
        text = " ".join(map(self._text, carried[:SHOWN_VALUES]))
        rest = sum(len(param.words or (0,)) for param in carried[SHOWN_VALUES:])
        return text + (f" … (+{rest} registers)" if rest else "")

    def _text(self, param: ParamValue) -> str:
        if not self.typed:
            return f"0x{param.raw:04X}"
        value = param.value
        if value is None:  # a register of a value the frame does not carry whole
            return f"+{param.raw}"
        if isinstance(value, float) and param.words is not None and len(param.words) == 2:
            return f"{value:.7g}"  # an f32 holds 7 significant digits
        return str(value)

    def summary(self, pdu: Pdu | None, params: Sequence[ParamValue]) -> str | None:
        """A summary of a register PDU in this format, with the values of its ``params`` (the
        decoding's); ``None`` for PDUs it does not cover."""
        start = params[0].address if params else None
        match pdu:
            case ReadRequest(function=function, address=address, count=count):
                return f"read {TABLE_NAMES[function]} {self.span(function, address, count)} ({count})"
            case RegistersResponse(function=function, values=values):
                function = 4 if function == 4 else 3
                where = f" {self.span(function, start, len(values))}" if start is not None else ""
                return f"{TABLE_NAMES[function]}{where} = {self.values(params) if params else self._hex(values)}"
            case WriteSingle(function=5, address=address, value=value):
                state = "ON" if value == COIL_ON else ("OFF" if value == 0 else f"invalid 0x{value:04X}")
                return f"write coil {self.address(5, address)} = {state}"
            case WriteSingle(function=function, address=address):
                return f"write HR {self.address(function, address)} = {self.values(params)}"
            case WriteRegistersRequest(address=address, values=values):
                return f"write HR {self.span(16, address, len(values))} = {self.values(params)}"
            case WriteMultipleResponse(function=function, address=address, count=count):
                return f"wrote {TABLE_NAMES[function]} {self.span(function, address, count)} ({count})"
            case ReadWriteRequest():
                read = self.span(23, pdu.read_address, pdu.read_count)
                write = self.span(23, pdu.write_address, len(pdu.values))
                written = [param for param in params if param.raw is not None or param.words is not None]
                return f"read HR {read} ({pdu.read_count}), write HR {write} = {self.values(written)}"
        return None

    @staticmethod
    def _hex(words: tuple[int, ...]) -> str:
        """An answer's words where no request says whose they are (no params)."""
        text = " ".join(f"0x{word:04X}" for word in words[:SHOWN_VALUES])
        return text + (f" … (+{len(words) - SHOWN_VALUES} registers)" if len(words) > SHOWN_VALUES else "")
