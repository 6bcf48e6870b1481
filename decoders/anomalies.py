"""The kinds of anomaly a frame can show, and which frames of a batch show each (in columns).

One definition for ``stats``' counts, the report's evidence and the Parquet ``anomalies`` table:
the CRC errors of frames, the flags, exception and noise roles.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import ROLE_CODE, MessageBatch, Role

#: Kinds of anomaly: key (the JSONL flag name where it is a flag), title, what it means on a wire.
KINDS: dict[str, tuple[str, str]] = {
    "crc_error": ("CRC error", "the frame's checksum does not match its bytes: a disturbed line, a bad "
                  "termination, or two transmitters at once"),
    "timeout": ("timeout", "a request no answer came for in time"),
    "exception": ("exception", "the slave refused the request; the code says why"),
    "unexpected": ("unexpected answer", "an answer no open request matches"),
    "retry": ("retry", "the master repeated a request that had no answer"),
    "gap_1_5": ("gap inside a frame", "a silence longer than 1.5 characters inside a frame"),
    "short_idle": ("short idle", "less than 3.5 characters of silence before the frame"),
    "truncated": ("truncated", "the frame stops before its expected length"),
    "bad_length": ("bad length", "the frame's length does not fit its function"),
    "uart_error": ("UART error", "characters with a framing or parity error"),
    "noise": ("noise", "bytes that form no frame"),
}
_FLAG_OF = {"timeout": FrameFlag.TIMEOUT, "unexpected": FrameFlag.UNEXPECTED, "retry": FrameFlag.RETRY,
            "gap_1_5": FrameFlag.GAP_1_5, "short_idle": FrameFlag.SHORT_IDLE, "truncated": FrameFlag.TRUNCATED,
            "bad_length": FrameFlag.BAD_LENGTH, "uart_error": FrameFlag.UART_ERROR}
_NOISE, _EXCEPTION = ROLE_CODE[Role.NOISE], ROLE_CODE[Role.EXCEPTION]


def anomaly_masks(messages: MessageBatch) -> dict[str, npt.NDArray[np.bool_]]:
    """For each kind of :data:`KINDS`, which messages of the batch show it."""
    flags, role = messages.flags, messages.role
    masks = {"crc_error": ~messages.frames.crc_ok & (role != _NOISE), "exception": role == _EXCEPTION}
    masks |= {kind: (flags & flag) != 0 for kind, flag in _FLAG_OF.items()}
    masks["noise"] = role == _NOISE
    return {kind: masks[kind] for kind in KINDS}
