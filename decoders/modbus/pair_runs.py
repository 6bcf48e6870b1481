"""The matcher's shortcut: runs of request/answer pairs whose outcome is certain, found by numpy.

From a state with nothing open, a request followed by its answer (same slave
and function, fitting content, a valid answer CRC, well within the shortest response timeout)
has one possible outcome; :class:`decoders.modbus.matcher.Matcher` settles such runs in bulk and
visits the frames outside them one by one (``bulk=False`` visits all: the reference path),
reading them from :func:`frame_lists`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameBatch
from decoders.modbus.codes import BROADCAST_ADDRESS
from decoders.modbus.shapes import FITS_REQUEST, FITS_RESPONSE, IS_EXCEPTION, Shapes


def pair_runs(frames: FrameBatch, shapes: Shapes, active: npt.NDArray[np.intp], *,
              within_ns: int) -> npt.NDArray[np.int64]:
    """For each active frame k: how many request/answer pairs start there, one after the
    other, whose outcome is certain from a state with nothing open (0 if none): each answer
    comes ``within_ns`` of its request (less than any response timeout)."""
    if len(active) < 2:
        return np.zeros(len(active), np.int64)
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
    return runs


#: Frames in the matcher loop's first window of lists (see :func:`frame_lists`).
FIRST_WINDOW = 64


def frame_lists(frames: FrameBatch, shapes: Shapes, start: int, stop: int) -> tuple[
        list[int], list[int], list[int], list[int], list[int], list[int], list[bool], list[int], list[int]]:
    """The columns the matcher's loop reads, as lists of frames ``start`` to ``stop``: offsets
    (one more), slave, function, shape, request and response keys, CRC, start and end times.

    On a healthy bus the loop visits few frames of a batch (bulk runs settle the rest): the
    answer to the request the batch before left open, then the batch's own last request. Lists
    of the whole batch cost more than the loop then. So the first window is ``FIRST_WINDOW``
    frames, and a frame past it gets the rest of the batch: a bus that needs the loop
    throughout is read once more.
    """
    window = slice(start, stop)
    return (frames.offsets[start : stop + 1].tolist(), shapes.slave[window].tolist(),
            shapes.function[window].tolist(), shapes.shape[window].tolist(), shapes.request_key[window].tolist(),
            shapes.response_key[window].tolist(), frames.crc_ok[window].tolist(),
            frames.t_start_ns[window].tolist(), frames.t_end_ns[window].tolist())
