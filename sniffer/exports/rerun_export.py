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
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import rerun as rr
import rerun.blueprint as rrb

from decoders.message import NONE, ROLE_CODE, AnnotatedBatch, Decoding, Message, Role
from sniffer.exports.levels import ERROR, FLAG_SUFFIXES, INFO, TIMEOUT, WARNING, errors, log_levels

APPLICATION = "rtusniff"
FLUSH_ROWS = 200_000
MAX_UNNAMED_SERIES = 64
SECOND_NS = 1_000_000_000
_LEVEL_NAMES = {INFO: "INFO", WARNING: "WARN", ERROR: "ERROR"}
KEPT_PARTS = 4096
_EXCEPTION = ROLE_CODE[Role.EXCEPTION]


@dataclass
class _Parts:
    """What one decoding puts on the timeline: its log entity and text (after the frame index),
    numeric params (entity, value, series name), states (entity, text), its latency series."""

    log_entity: str
    text: str
    scalars: list[tuple[str, float, str]] = field(default_factory=list)
    states: list[tuple[str, str]] = field(default_factory=list)
    latency_entity: str = ""
    latency_name: str = ""


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
        self._parts: dict[Decoding, _Parts] = {}
        self._unnamed: dict[int, set[int]] = {}
        self._second: int | None = None
        self._wire_ns = 0
        self._errors = 0
        self._rows = 0

    def messages(self, batch: AnnotatedBatch) -> None:
        positions = batch.positions()
        messages, frames = batch.messages, batch.messages.frames
        t_start = frames.t_start_ns[positions]
        failed = errors(messages)[positions]
        self._bus(t_start, frames.t_end_ns[positions] - t_start, failed, first_index=frames.first_index)
        columns = zip(
            t_start.tolist(), log_levels(messages)[positions].tolist(), messages.flags[positions].tolist(),
            messages.slave[positions].tolist(), messages.latency_ns[positions].tolist(),
            frames.crc_ok[positions].tolist(), messages.role[positions].tolist(), strict=True,
        )
        first, decodings, rows = frames.first_index, batch.decodings, messages.rows()
        for position, (t, level, flags, slave, latency, crc_ok, role) in zip(positions, columns, strict=True):
            decoding, index = decodings[position], first + position
            if slave == NONE:
                self._log("bus/noise", t, index, decoding.summary, "WARN")
                continue
            parts = self._parts.get(decoding) or self._decoding_parts(decoding, rows[position])
            self._log(parts.log_entity, t, index, f"#{index}{parts.text}{FLAG_SUFFIXES[flags]}", _LEVEL_NAMES[level])
            for entity, value, name in parts.scalars:
                self._scalar(entity, t, index, value, name)
            for entity, text in parts.states:
                self._state(entity, t, index, text)
            if latency != NONE and parts.latency_entity and crc_ok:
                self._scalar(parts.latency_entity, t, index, latency / 1e6, parts.latency_name)
            if flags & TIMEOUT:
                self._scalar(f"slaves/{slave}/errors/timeout", t, index, 1.0, "timeout errors", points=True)
            if not crc_ok:
                self._scalar(f"slaves/{slave}/errors/crc", t, index, 1.0, "crc errors", points=True)
            if role == _EXCEPTION:
                self._scalar(f"slaves/{slave}/errors/exception", t, index, 1.0, "exception errors", points=True)
        if self._rows >= FLUSH_ROWS:
            self._flush()

    def _decoding_parts(self, decoding: Decoding, message: Message) -> _Parts:
        """What a decoding puts on the timeline, built once per decoding."""
        slave = message.slave
        assert slave is not None
        base = f"slaves/{slave}"
        self._slaves.add(slave)
        parts = _Parts(f"{base}/log", f" {message.role.value}: {decoding.summary}")
        for param in decoding.params:
            if param.raw is None:
                continue
            code = param.code or str(param.address)
            if param.code is None and not self._may_plot(slave, param.address):
                continue
            if isinstance(param.value, int | float):
                name = f"{code} ({param.unit})" if param.unit else code
                parts.scalars.append((f"{base}/params/{_path(code)}", float(param.value), name))
            elif isinstance(param.value, str) and param.code is not None:
                parts.states.append((f"{base}/state/{_path(code)}", f"{code}: {param.value}"))
        if message.function is not None:
            parts.latency_entity = f"{base}/latency_ms/fc{message.function}"
            parts.latency_name = f"latency FC {message.function} (ms)"
        if len(self._parts) >= KEPT_PARTS:
            self._parts.clear()
        self._parts[decoding] = parts
        return parts

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

    def _bus(self, t_start: npt.NDArray[np.int64], wire_ns: npt.NDArray[np.int64], failed: npt.NDArray[np.bool_],
             *, first_index: int) -> None:
        """Bus load and errors per second, a point at the start of each second once it is over."""
        if not len(t_start):
            return
        seconds = t_start // SECOND_NS
        starts = np.flatnonzero(np.diff(seconds, prepend=seconds[0] - 1))
        wire = np.add.reduceat(wire_ns, starts).tolist()
        failures = np.add.reduceat(failed.astype(np.int64), starts).tolist()
        for second, first, wire_sum, error_count in zip(seconds[starts].tolist(), starts.tolist(), wire, failures,
                                                         strict=True):
            if self._second is not None and second != self._second:
                t, index = self._second * SECOND_NS, first_index + first
                self._scalar("bus/load_percent", t, index, 100 * self._wire_ns / SECOND_NS, "bus load (%)")
                self._scalar("bus/errors_per_s", t, index, float(self._errors), "errors per second")
                self._wire_ns = self._errors = 0
            self._second = second
            self._wire_ns += wire_sum
            self._errors += error_count

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
