"""A Rerun timeline of the capture. The only module that calls the Rerun SDK (tested with 0.41).

Timelines: ``capture_time`` (the frames' start times) and ``frame`` (the frame index).
Entities, per slave N: ``slaves/N/log`` (every frame's summary, with a level),
``slaves/N/params/CODE`` (every numeric register value: speeds, currents, setpoints),
``slaves/N/latency_ms/fcF`` (latency per request type), ``slaves/N/errors/{crc,timeout,exception}``
(a point for each), ``slaves/N/state/CODE`` (a status word's state, logged when it changes);
and for the bus: ``bus/load_percent`` and ``bus/errors_per_s`` per second, ``bus/noise``.

Rows are buffered per entity and sent in columns (``send_columns``), which is hundreds of
times faster than logging row by row. A blueprint opens the recording with the plots on top
and the logs below.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from decoders.frame import FrameFlag
from decoders.message import Message, Role
from sniffer.exports.mcap_export import log_level

APPLICATION = "rtusniff"
FLUSH_ROWS = 200_000
MAX_UNNAMED_SERIES = 64
SECOND_NS = 1_000_000_000
_LEVEL_NAMES = {1: "DEBUG", 2: "INFO", 3: "WARN", 4: "ERROR"}


@dataclass
class _Rows:
    """Buffered rows of one entity."""

    times: list[int] = field(default_factory=list)
    frames: list[int] = field(default_factory=list)
    values: list[float] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    levels: list[str] = field(default_factory=list)


class RerunExporter:
    """Buffers rows per entity and sends them in columns; ``close`` writes the file."""

    def __init__(self, path: str | None, spawn: bool = False) -> None:
        self._rec = rr.RecordingStream(APPLICATION)
        self._rec.set_log_time_enabled(False)
        self._rec.set_log_tick_enabled(False)
        if spawn:
            self._rec.spawn()
        if path is not None:
            self._rec.save(path)
        self._scalars: defaultdict[str, _Rows] = defaultdict(_Rows)
        self._logs: defaultdict[str, _Rows] = defaultdict(_Rows)
        self._series: dict[str, str] = {}
        self._states: dict[str, str] = {}
        self._slaves: set[int] = set()
        self._unnamed: dict[int, set[int]] = {}
        self._second: int | None = None
        self._wire_ns = 0
        self._errors = 0
        self._rows = 0
        self.rows_sent = 0

    def messages(self, messages: Iterable[Message]) -> None:
        for message in messages:
            self._message(message)
        if self._rows >= FLUSH_ROWS:
            self._flush()

    def _message(self, message: Message) -> None:
        frame = message.frame
        t, index = frame.t_start_ns, frame.index
        self._bus(message)
        if message.slave is None:
            self._log("bus/noise", t, index, message.summary, "WARN")
            return
        base = f"slaves/{message.slave}"
        self._slaves.add(message.slave)
        flags = f" [{' '.join(message.flags.names)}]" if message.flags else ""
        self._log(f"{base}/log", t, index, f"#{index} {message.role.value}: {message.summary}{flags}",
                  _LEVEL_NAMES[log_level(message)])
        for param in message.params:
            if param.raw is None:
                continue
            code = param.code or str(param.address)
            if param.code is None and not self._may_plot(message.slave, param.address):
                continue
            if isinstance(param.value, int | float):
                self._scalar(f"{base}/params/{_path(code)}", t, index, float(param.value),
                             f"{code} ({param.unit})" if param.unit else code)
            elif isinstance(param.value, str) and param.code is not None:
                self._state(f"{base}/state/{_path(code)}", t, index, f"{code}: {param.value}")
        if message.latency_ns is not None and message.function is not None and message.frame.crc_ok:
            self._scalar(f"{base}/latency_ms/fc{message.function}", t, index, message.latency_ns / 1e6,
                         f"latency FC {message.function} (ms)")
        for kind, happened in (("crc", not frame.crc_ok), ("timeout", bool(message.flags & FrameFlag.TIMEOUT)),
                               ("exception", message.role is Role.EXCEPTION)):
            if happened:
                self._scalar(f"{base}/errors/{kind}", t, index, 1.0, f"{kind} errors", points=True)

    def _may_plot(self, slave: int, address: int) -> bool:
        """Registers without a name are plotted for the first ``MAX_UNNAMED_SERIES`` addresses
        of a slave: a capture that reads thousands of addresses would drown the viewer."""
        seen = self._unnamed.setdefault(slave, set())
        if address in seen:
            return True
        if len(seen) >= MAX_UNNAMED_SERIES:
            return False
        seen.add(address)
        return True

    def _bus(self, message: Message) -> None:
        frame = message.frame
        second = frame.t_start_ns // SECOND_NS
        if self._second is not None and second != self._second:
            t = self._second * SECOND_NS
            self._scalar("bus/load_percent", t, frame.index, 100 * self._wire_ns / SECOND_NS, "bus load (%)")
            self._scalar("bus/errors_per_s", t, frame.index, float(self._errors), "errors per second")
            self._wire_ns = self._errors = 0
        self._second = second
        self._wire_ns += frame.t_end_ns - frame.t_start_ns
        self._errors += int(not frame.crc_ok or bool(message.flags & FrameFlag.TIMEOUT)
                            or message.role is Role.EXCEPTION)

    def _scalar(self, entity: str, t: int, index: int, value: float, name: str, *, points: bool = False) -> None:
        rows = self._scalars[entity]
        rows.times.append(t)
        rows.frames.append(index)
        rows.values.append(value)
        self._rows += 1
        if entity not in self._series:
            self._series[entity] = name
            style = rr.SeriesPoints(names=name) if points else rr.SeriesLines(names=name)
            self._rec.log(entity, style, static=True)

    def _log(self, entity: str, t: int, index: int, text: str, level: str) -> None:
        rows = self._logs[entity]
        rows.times.append(t)
        rows.frames.append(index)
        rows.texts.append(text)
        rows.levels.append(level)
        self._rows += 1

    def _state(self, entity: str, t: int, index: int, text: str) -> None:
        if self._states.get(entity) != text:
            self._states[entity] = text
            self._log(entity, t, index, text, "INFO")

    def _flush(self) -> None:
        for entity, rows in self._scalars.items():
            if rows.times:
                self._rec.send_columns(entity, indexes=_indexes(rows),
                                       columns=rr.Scalars.columns(scalars=np.array(rows.values)))
        for entity, rows in self._logs.items():
            if rows.times:
                self._rec.send_columns(entity, indexes=_indexes(rows),
                                       columns=rr.TextLog.columns(text=rows.texts, level=rows.levels))
        self.rows_sent += self._rows
        self._rows = 0
        self._scalars.clear()
        self._logs.clear()

    def close(self) -> None:
        self._flush()
        self._rec.send_blueprint(self.blueprint())
        self._rec.flush()
        self._rec.disconnect()

    def blueprint(self) -> rrb.Blueprint:
        """Plots on top (one per slave, and the bus), logs below."""
        plots = [rrb.TimeSeriesView(origin=f"/slaves/{slave}", name=f"slave {slave}") for slave in sorted(self._slaves)]
        plots.append(rrb.TimeSeriesView(origin="/bus", name="bus"))
        return rrb.Blueprint(
            rrb.Vertical(rrb.Grid(*plots), rrb.TextLogView(origin="/", name="frames"), row_shares=[3, 2]),
            rrb.TimePanel(expanded=True),
        )


def _indexes(rows: _Rows) -> list[rr.TimeColumn]:
    return [
        rr.TimeColumn("capture_time", timestamp=np.array(rows.times, np.int64).astype("datetime64[ns]")),
        rr.TimeColumn("frame", sequence=np.array(rows.frames, np.int64)),
    ]


def _path(code: str) -> str:
    """An entity path part from a parameter code (``NM1→ETA`` → ``NM1_ETA``)."""
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in code)
