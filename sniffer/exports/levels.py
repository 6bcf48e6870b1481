"""What the exported logs (Foxglove's and Rerun's) say about each frame beyond its summary: a
level — ERROR for CRC errors, timeouts and exceptions; WARNING for noise, timing and retry
flags, unexpected answers and UART errors; INFO for the rest (numbers are ``foxglove.Log`` levels) — and
its flags as a suffix of the log text."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import ROLE_CODE, MessageBatch, Role

INFO, WARNING, ERROR = 2, 3, 4
#: Flags come as ints from the columns: no enum arithmetic on the hot path.
TIMEOUT = int(FrameFlag.TIMEOUT)
WARNING_FLAGS = int(FrameFlag.GAP_1_5 | FrameFlag.SHORT_IDLE | FrameFlag.RETRY | FrameFlag.UNEXPECTED
                    | FrameFlag.UART_ERROR)
#: `` [gap_1_5 retry]`` by flag value; empty without flags.
FLAG_SUFFIXES = [f" [{' '.join(FrameFlag(value).names)}]" if value else "" for value in range(1 << len(FrameFlag))]


def errors(batch: MessageBatch) -> npt.NDArray[np.bool_]:
    """CRC errors, timeouts and exceptions, in columns (also what a bus's error rate counts)."""
    failed: npt.NDArray[np.bool_] = (
        ~batch.frames.crc_ok | ((batch.flags & TIMEOUT) != 0) | (batch.role == ROLE_CODE[Role.EXCEPTION])
    )
    return failed


def log_levels(batch: MessageBatch) -> npt.NDArray[np.uint8]:
    """Each message's level, in columns."""
    levels = np.full(len(batch), INFO, np.uint8)
    levels[(batch.flags & WARNING_FLAGS) != 0] = WARNING
    levels[errors(batch)] = ERROR
    levels[batch.role == ROLE_CODE[Role.NOISE]] = WARNING
    return levels
