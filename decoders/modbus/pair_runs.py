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
from decoders.message import ROLE_CODE, Role
from decoders.modbus.codes import BROADCAST_ADDRESS
from decoders.modbus.shapes import FITS_REQUEST, FITS_RESPONSE, IS_EXCEPTION, Shapes
from decoders.runs import spread

_REQUEST, _RESPONSE = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.RESPONSE]


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


#: Frames in each window of lists the matcher's loop reads (see :func:`frame_lists`).
WINDOW = 64


def frame_lists(frames: FrameBatch, shapes: Shapes, start: int, stop: int) -> tuple[
        list[int], list[int], list[int], list[int], list[int], list[int], list[bool], list[int], list[int]]:
    """The columns the matcher's loop reads, as lists of frames ``start`` to ``stop``: offsets
    (one more), slave, function, shape, request and response keys, CRC, start and end times.

    The loop visits few frames of a batch: on a healthy bus, bulk runs settle all but the answer
    to the request the batch before left open and the batch's own last request; on a bus with
    faults (exceptions, timeouts, retries), the frames around each fault. Lists of the whole
    batch cost more than the loop then, so each frame visited past a window starts the next,
    ``WINDOW`` frames long, not the rest of the batch (faster on mixed traffic, whose faults
    come in clusters, and on a bus whose every frame is visited).
    """
    window = slice(start, stop)
    return (frames.offsets[start : stop + 1].tolist(), shapes.slave[window].tolist(),
            shapes.function[window].tolist(), shapes.shape[window].tolist(), shapes.request_key[window].tolist(),
            shapes.response_key[window].tolist(), frames.crc_ok[window].tolist(),
            frames.t_start_ns[window].tolist(), frames.t_end_ns[window].tolist())


class SettledRuns:
    """The runs of pairs the matcher settles in bulk in a batch (``runs``: first active frame and
    how many pairs), whose roles, requests and latencies are written in one step once its loop is
    done; ``gaps``: the latency each active frame would have as the answer to the one before it."""

    def __init__(self, frames: FrameBatch, active: npt.NDArray[np.intp]) -> None:
        self.frames, self.active = frames, active
        self.runs: list[tuple[int, int]] = []
        self.gaps = np.maximum(frames.t_start_ns[active[1:]] - frames.t_end_ns[active[:-1]], 0)

    def write(self, columns: dict[str, npt.NDArray[np.int64]], first: int) -> None:
        if not self.runs:
            return
        if len(self.runs) == 1:  # a healthy bus: one run a batch
            start, count = self.runs[0]
            at = np.arange(start, start + 2 * count, 2)
        else:
            starts, pairs = np.array(self.runs, np.int64).T
            at = spread(starts, pairs, 2)
        asks, answers = self.active[at], self.active[at + 1]
        columns["role"][first + asks] = _REQUEST
        columns["role"][first + answers] = _RESPONSE
        columns["request_index"][first + answers] = self.frames.first_index + asks
        columns["latency_ns"][first + answers] = self.gaps[at]
