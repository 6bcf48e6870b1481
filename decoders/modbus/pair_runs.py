"""The matcher's shortcut: runs of request/answer pairs whose outcome is certain, found by numpy.

From a state with nothing open, a request followed by its answer (same slave
and function, fitting content, a valid answer CRC, well within the shortest response timeout)
has one possible outcome; :class:`decoders.modbus.matcher.Matcher` settles such runs in bulk and
visits the frames outside them one by one (``bulk=False`` visits all: the reference path).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameBatch
from decoders.modbus.codes import BROADCAST_ADDRESS
from decoders.modbus.shapes import FITS_REQUEST, FITS_RESPONSE, IS_EXCEPTION, Shapes


def pair_runs(frames: FrameBatch, shapes: Shapes, active: npt.NDArray[np.intp], *, within_ns: int) -> list[int]:
    """For each active frame k: how many request/answer pairs start there, one after the
    other, whose outcome is certain from a state with nothing open (0 if none): each answer
    comes ``within_ns`` of its request (less than any response timeout)."""
    if len(active) < 2:
        return [0] * len(active)
    slave, raw, shape = shapes.slave[active], shapes.function[active], shapes.shape[active]
    request_key, response_key = shapes.request_key[active], shapes.response_key[active]
    ask, answer = slice(0, -1), slice(1, None)
    latency = frames.t_start_ns[active][answer] - frames.t_end_ns[active][ask]
    pair = np.zeros(len(active), np.bool_)
    pair[:-1] = (
        ((shape[ask] & (FITS_REQUEST | IS_EXCEPTION)) == FITS_REQUEST)
        & (slave[ask] != BROADCAST_ADDRESS)
        & ((shape[answer] & (FITS_RESPONSE | IS_EXCEPTION)) == FITS_RESPONSE)
        & (slave[answer] == slave[ask])
        & (raw[answer] == raw[ask])
        & (response_key[answer] == request_key[ask])
        & frames.crc_ok[active][answer]
        & (latency < within_ns)
    )
    runs = np.zeros(len(active), np.int64)
    for parity in (0, 1):
        starts = pair[parity::2]
        breaks = np.where(starts, len(starts), np.arange(len(starts)))
        next_break = np.minimum.accumulate(breaks[::-1])[::-1]
        runs[parity::2] = next_break - np.arange(len(starts))
    return runs.tolist()
