"""Register values and addresses as a device's manual writes them, for devices without a profile.

* **Values** (``kind``): ``u16``, ``s16``, ``hex``, and the 32-bit ``u32``, ``s32``, ``f32``
  (IEEE 754) built from two registers in a ``word_order``: ``big`` (high word first, "ABCD",
  what Modbus's own big-endian order suggests) or ``little`` (low word first, "CDAB", common
  in PLCs). A trailing odd register is written as ``u16`` after a ``+``.
* **Addresses** (``addressing``): ``wire`` (the number sent, from 0), ``1`` (from 1, as most
  manuals number registers) or ``4x`` (the Modicon reference: 40001 + wire for holding
  registers, 30001 for input registers, 00001 for coils, 10001 for discrete inputs).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

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

KINDS = ("u16", "s16", "hex", "u32", "s32", "f32")
WORD_ORDERS = ("big", "little")
ADDRESSINGS = ("wire", "1", "4x")
#: Values written out before "… (+N)".
SHOWN_VALUES = 16


@dataclass(frozen=True)
class RegisterFormat:
    kind: str = "hex"
    word_order: str = "big"
    addressing: str = "wire"

    def __post_init__(self) -> None:
        if self.kind not in KINDS or self.word_order not in WORD_ORDERS or self.addressing not in ADDRESSINGS:
            raise ValueError(f"register format {self} is not one of {KINDS} × {WORD_ORDERS} × {ADDRESSINGS}")

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

    def values(self, words: tuple[int, ...]) -> str:
        """The registers' values, space separated."""
        texts = self._value_texts(words[: SHOWN_VALUES * (2 if self.kind in ("u32", "s32", "f32") else 1)])
        text = " ".join(texts)
        shown = len(texts) * (2 if self.kind in ("u32", "s32", "f32") else 1)
        return text + (f" … (+{len(words) - shown} registers)" if len(words) > shown else "")

    def _value_texts(self, words: tuple[int, ...]) -> list[str]:
        if self.kind == "u16":
            return [str(w) for w in words]
        if self.kind == "s16":
            return [str(w - 0x10000 if w & 0x8000 else w) for w in words]
        if self.kind == "hex":
            return [f"0x{w:04X}" for w in words]
        pairs = [(words[i], words[i + 1]) for i in range(0, len(words) - 1, 2)]
        texts = [self._double(high, low) if self.word_order == "big" else self._double(low, high)
                 for high, low in pairs]
        if len(words) % 2:
            texts.append(f"+{words[-1]}")
        return texts

    def _double(self, high: int, low: int) -> str:
        raw = struct.pack(">HH", high, low)
        if self.kind == "u32":
            return str(struct.unpack(">I", raw)[0])
        if self.kind == "s32":
            return str(struct.unpack(">i", raw)[0])
        return f"{struct.unpack('>f', raw)[0]:.7g}"

    def summary(self, pdu: Pdu | None, read_start: int | None) -> str | None:
        """A summary of a register PDU in this format (``read_start``: where the answered read
        began), ``None`` for PDUs it does not cover."""
        match pdu:
            case ReadRequest(function=function, address=address, count=count):
                return f"read {TABLE_NAMES[function]} {self.span(function, address, count)} ({count})"
            case RegistersResponse(function=function, values=values):
                function = 4 if function == 4 else 3
                where = f" {self.span(function, read_start, len(values))}" if read_start is not None else ""
                return f"{TABLE_NAMES[function]}{where} = {self.values(values)}"
            case WriteSingle(function=5, address=address, value=value):
                state = "ON" if value == COIL_ON else ("OFF" if value == 0 else f"invalid 0x{value:04X}")
                return f"write coil {self.address(5, address)} = {state}"
            case WriteSingle(function=function, address=address, value=value):
                return f"write HR {self.address(function, address)} = {self.values((value,))}"
            case WriteRegistersRequest(address=address, values=values):
                return f"write HR {self.span(16, address, len(values))} = {self.values(values)}"
            case WriteMultipleResponse(function=function, address=address, count=count):
                return f"wrote {TABLE_NAMES[function]} {self.span(function, address, count)} ({count})"
            case ReadWriteRequest():
                read = self.span(23, pdu.read_address, pdu.read_count)
                write = self.span(23, pdu.write_address, len(pdu.values))
                return f"read HR {read} ({pdu.read_count}), write HR {write} = {self.values(pdu.values)}"
        return None
