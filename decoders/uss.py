"""USS telegrams (Siemens/NORD universal serial interface), as NORD drives speak them on
the same RS485 port as Modbus.

A telegram is ``STX LGE ADR <net data> BCC``: STX = 0x02, LGE counts the bytes after
it (ADR, net data, BCC), BCC is the XOR of every byte before it. The net data of the
NORD PPO types is a parameter channel (PKW: PKE, IND, PWE1, PWE2) and/or process data
(PZD: control or status word, then setpoints or actual values) (NORD BU 0050, NORD:62-111).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from functools import reduce
from operator import xor

STX = 0x02
#: LGE of the NORD PPO types: PPO 3 (2 PZD), PPO 1 (4 PKW + 2 PZD) or PPO 4 (6 PZD),
#: PPO 2 (4 PKW + 6 PZD). Only these are recognised, which keeps noise from passing.
PPO_LGE = {6: (0, 2), 14: (4, 2), 22: (4, 6)}
MIN_LENGTH = 8
#: AK values of a response that reports an error (NORD:104-105).
AK_ERROR = 7


def uss_length(head: bytes) -> int | None:
    """The telegram's whole length if ``head`` starts with a valid USS telegram of a NORD PPO type."""
    if len(head) < MIN_LENGTH or head[0] != STX or head[1] not in PPO_LGE:
        return None
    length = head[1] + 2
    if len(head) < length or reduce(xor, head[: length - 1], 0) != head[length - 1]:
        return None
    return length


@dataclass(frozen=True, slots=True)
class UssTelegram:
    """A decoded USS telegram."""

    address: int
    broadcast: bool
    pke: int | None
    index: int | None
    pwe: tuple[int, ...]
    pzd: tuple[int, ...]

    @property
    def ak(self) -> int | None:
        """Request or response id (PKE bits 12-15)."""
        return None if self.pke is None else self.pke >> 12

    @property
    def pnu(self) -> int | None:
        """Parameter number (PKE bits 0-10)."""
        return None if self.pke is None else self.pke & 0x07FF

    def summary(self) -> str:
        parts = [f"USS {'broadcast' if self.broadcast else f'address {self.address}'}"]
        if self.pke is not None:
            pwe = " ".join(f"{w:04X}" for w in self.pwe)
            parts.append(f"PKW AK {self.ak} P{self.pnu} index {self.index} PWE {pwe}")
        if self.pzd:
            parts.append("PZD " + " ".join(f"{w:04X}" for w in self.pzd))
        return ", ".join(parts)


def parse_uss(telegram: bytes) -> UssTelegram:
    """Decode a telegram that :func:`uss_length` accepted."""
    pkw_words, pzd_words = PPO_LGE[telegram[1]]
    words = struct.unpack(f">{pkw_words + pzd_words}H", telegram[3:-1])
    pkw, pzd = words[:pkw_words], words[pkw_words:]
    return UssTelegram(
        address=telegram[2] & 0x1F,
        broadcast=bool(telegram[2] & 0x20),
        pke=pkw[0] if pkw else None,
        index=pkw[1] if pkw else None,
        pwe=tuple(pkw[2:]),
        pzd=tuple(pzd),
    )
