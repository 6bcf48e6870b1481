"""Length rules and headers: what the bytes at a frame's start say about the frame.

Shared by the best parse (:mod:`decoders.framing.best_parse`), its evidence
(:mod:`decoders.framing.evidence`) and the vectorised fast path
(:mod:`decoders.framing.fast`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from decoders.modbus.codecs import LAYOUTS
from decoders.modbus.codes import BROADCAST_ADDRESS, EXCEPTION_BIT
from decoders.modbus.layouts import exception_length

MIN_ADU = 4
MAX_ADDRESS = 247

#: (slave, function, bytes) of the request that awaits its response, if any: its bytes tell
#: a master's retry (the same request again) from an answer (see :mod:`decoders.framing.evidence`).
OpenRequest = tuple[int, int, bytes] | None


def awaits(open_request: OpenRequest, slave: int, function: int) -> bool:
    """Whether ``open_request`` awaits an answer from ``slave`` to ``function``."""
    return open_request is not None and open_request[0] == slave and open_request[1] == function


def rule_lengths(adu: bytes) -> list[int | None]:
    """The lengths the length rules give for ``adu``'s function code, request first.

    ``None`` stands for a direction whose length is not yet known from these bytes;
    an empty list means the function code has no length rule.
    """
    if len(adu) < 2:
        return []
    function = adu[1]
    if function & EXCEPTION_BIT:
        return [exception_length(adu)] if (function & ~EXCEPTION_BIT) in LAYOUTS else []
    layout = LAYOUTS.get(function)
    if layout is None:
        return []
    request, response = layout.request(adu), layout.response(adu)
    return [request] if request == response else [request, response]


def after_frame(frame: bytes, open_request: OpenRequest) -> OpenRequest:
    """The open request once ``frame`` (CRC-valid) has passed on the wire."""
    slave, function = frame[0], frame[1]
    if function & EXCEPTION_BIT:
        return None
    lengths = rule_lengths(frame)
    answers = awaits(open_request, slave, function) and len(frame) == (lengths[-1] if lengths else -1)
    if answers or slave == BROADCAST_ADDRESS or not lengths or len(frame) != lengths[0]:
        return None
    return (slave, function, frame)


#: Frame starts or stops: a list, or a column.
Positions = Sequence[int] | npt.NDArray[np.int64]
#: How many frames back the open request is replayed from (only a run of echo frames
#: longer than this could make it differ from replaying them all).
REPLAY_FRAMES = 4


def replayed_open_request(
    data: bytes, frames: tuple[Positions, Positions], which: range, open_request: OpenRequest
) -> OpenRequest:
    """The open request after the whole frames ``which`` (indexes into ``frames``: their
    starts and stops in ``data``), from ``open_request`` before them."""
    starts, stops = frames
    if len(which) > REPLAY_FRAMES:
        which, open_request = which[-REPLAY_FRAMES:], None
    for k in which:
        open_request = after_frame(data[int(starts[k]) : int(stops[k])], open_request)
    return open_request
