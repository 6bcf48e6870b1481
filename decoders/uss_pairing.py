"""Roles and pairing of USS telegrams (NORD drives on the Modbus wire; :mod:`decoders.uss`).

USS has no function code and no request/response layouts: a master's telegram and
the answer from the same address alternate. A telegram with the broadcast bit set
(ADR bit 5) is a broadcast; a telegram to an address with nothing open is a request;
the next one from that address is its answer, with its latency.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameBatch
from decoders.message import NONE, ROLE_CODE, Role

REQUEST = ROLE_CODE[Role.REQUEST]
RESPONSE = ROLE_CODE[Role.RESPONSE]
BROADCAST = ROLE_CODE[Role.BROADCAST]
#: Bits of ADR: the address, and the broadcast flag.
ADDRESS_MASK = 0x1F
BROADCAST_BIT = 0x20

Columns = dict[str, npt.NDArray[np.int64]]


class UssPairing:
    """The telegrams awaiting an answer, per address, across batches."""

    def __init__(self) -> None:
        #: address → (index of the asking telegram, end of it in ns)
        self._open: dict[int, tuple[int, int]] = {}

    def assign(self, frames: FrameBatch, telegrams: npt.NDArray[np.intp], columns: Columns, first: int) -> None:
        """Set role, slave, request index and latency of the USS telegrams at positions
        ``telegrams`` of ``frames``, in ``columns`` from row ``first`` on."""
        offsets = frames.offsets.tolist()
        for i in telegrams.tolist():
            adr = frames.data[offsets[i] + 2]
            address, position = adr & ADDRESS_MASK, first + i
            columns["slave"][position] = address
            columns["function"][position] = NONE
            if adr & BROADCAST_BIT:
                columns["role"][position] = BROADCAST
                continue
            asked = self._open.pop(address, None)
            if asked is None:
                columns["role"][position] = REQUEST
                self._open[address] = (frames.first_index + i, int(frames.t_end_ns[i]))
            else:
                columns["role"][position] = RESPONSE
                columns["request_index"][position] = asked[0]
                columns["latency_ns"][position] = max(0, int(frames.t_start_ns[i]) - asked[1])
