"""How the tables write a frame's time: ``--time utc|local|relative``, a column at a time.

``utc`` and ``local`` write ``HH:MM:SS.ffffff`` (the date goes on a line of its own at the
start and wherever the capture crosses midnight); ``relative`` writes seconds since the first
frame of the part of the capture read (its first frame, or the window's), ``12.345678``, and
needs no dates.
"""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import numpy.typing as npt

MODES = ("utc", "local", "relative")
NS_PER_S = 1_000_000_000
SECONDS_PER_DAY = 86_400
#: Local offsets are looked up once per quarter hour of the capture (no zone changes its
#: offset more often; some change it on the half hour).
OFFSET_STEP_S = 900


class Clock:
    """Formats times in one mode; ``relative`` counts from the first time it formats."""

    def __init__(self, mode: str = "utc") -> None:
        if mode not in MODES:
            raise ValueError(f"time mode {mode!r} is not one of {', '.join(MODES)}")
        self.mode = mode
        self.origin_ns: int | None = None

    @property
    def header(self) -> str:
        return {"utc": "time (UTC)", "local": "time (local)", "relative": "time s"}[self.mode]

    @property
    def zone(self) -> str:
        return "UTC" if self.mode == "utc" else "local time"

    def texts(self, t_ns: npt.NDArray[np.int64]) -> list[str]:
        """Each time as the mode writes it."""
        if not len(t_ns):
            return []
        if self.mode == "relative":
            if self.origin_ns is None:
                self.origin_ns = int(t_ns[0])
            micros = (t_ns - self.origin_ns) // 1000
            return [f"{value / 1e6:.6f}" for value in micros.tolist()]
        # A batch spans few distinct seconds: "HH:MM:SS" once per second, the microseconds per row.
        seconds, where = np.unique(self._wall_seconds(t_ns) % SECONDS_PER_DAY, return_inverse=True)
        clocks = [f"{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}" for s in seconds.tolist()]
        micros = ((t_ns % NS_PER_S) // 1000).tolist()
        return list(map("%s.%06d".__mod__, zip(map(clocks.__getitem__, where.reshape(-1).tolist()), micros,
                                                  strict=True)))

    def days(self, t_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        """The day number of each time in the mode's zone (all 0 for ``relative``)."""
        if self.mode == "relative":
            return np.zeros(len(t_ns), np.int64)
        return self._wall_seconds(t_ns) // SECONDS_PER_DAY

    def seconds_of_day(self, t_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        """Seconds since midnight in the mode's zone (``utc`` or ``local``)."""
        return self._wall_seconds(t_ns) % SECONDS_PER_DAY

    def date(self, t_ns: int) -> str:
        """``2026-11-24 22:13:20`` in the mode's zone."""
        seconds = t_ns // NS_PER_S
        moment = datetime.fromtimestamp(seconds, UTC)
        if self.mode == "local":
            moment = moment.astimezone()
        return f"{moment:%Y-%m-%d %H:%M:%S}"

    def _wall_seconds(self, t_ns: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        seconds = t_ns // NS_PER_S
        if self.mode == "utc":
            return seconds
        steps, where = np.unique(seconds // OFFSET_STEP_S, return_inverse=True)
        offsets = np.array([_local_offset(int(step) * OFFSET_STEP_S) for step in steps.tolist()], np.int64)
        return seconds + offsets[where.reshape(-1)]


def _local_offset(seconds: int) -> int:
    """Seconds the local zone is ahead of UTC at ``seconds`` since the epoch."""
    offset = datetime.fromtimestamp(seconds, UTC).astimezone().utcoffset()
    return 0 if offset is None else int(offset.total_seconds())
