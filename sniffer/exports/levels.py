"""The level of each frame in the exported logs (Foxglove's and Rerun's): ERROR for CRC
errors, timeouts and exceptions; WARNING for noise, timing and retry flags and unexpected
answers; INFO for the rest. Numbers are ``foxglove.Log`` levels."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import ROLE_CODE, MessageBatch, Role

INFO, WARNING, ERROR = 2, 3, 4
ERROR_FLAGS = FrameFlag.TIMEOUT
WARNING_FLAGS = FrameFlag.GAP_1_5 | FrameFlag.SHORT_IDLE | FrameFlag.RETRY | FrameFlag.UNEXPECTED


def log_levels(batch: MessageBatch) -> npt.NDArray[np.uint8]:
    """Each message's level, in columns."""
    flags, role = batch.flags, batch.role
    levels = np.full(len(batch), INFO, np.uint8)
    levels[(flags & int(WARNING_FLAGS)) != 0] = WARNING
    levels[~batch.frames.crc_ok | ((flags & int(ERROR_FLAGS)) != 0) | (role == ROLE_CODE[Role.EXCEPTION])] = ERROR
    levels[role == ROLE_CODE[Role.NOISE]] = WARNING
    return levels
