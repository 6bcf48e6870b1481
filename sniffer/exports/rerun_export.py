"""A Rerun timeline of the capture. With :mod:`sniffer.exports.rerun_rows`, the only modules that
call the Rerun SDK (tested with 0.41; imported through :mod:`sniffer.exports.rerun_sdk`).

Timelines: ``capture_time`` (the frames' start times) and ``frame`` (the frame index).
Entities, per slave N: ``slaves/N/log`` (every frame's summary, with a level),
``slaves/N/params/CODE`` (every numeric register value: speeds, currents, setpoints),
``slaves/N/latency_ms/fcF`` (latency per request type), ``slaves/N/errors/{crc,timeout,exception}``
(a point for each), ``slaves/N/state/CODE`` (a status word's state, logged when it changes);
and for the bus: ``bus/load_percent`` and ``bus/errors_per_s`` per second, ``bus/noise``.

Rows are buffered per entity and sent in columns (:mod:`sniffer.exports.rerun_rows`). A
blueprint opens the recording with the plots on top and the logs below.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from operator import attrgetter, itemgetter
from typing import cast

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch, Params
from decoders.distinct import distinct
from decoders.memo import Memo
from decoders.message import NONE, ROLE_CODE, ROLE_NAMES, ParamValue, Role
from sniffer.exports.levels import ERROR, FLAG_SUFFIXES, INFO, TIMEOUT, WARNING, errors, log_levels
from sniffer.exports.published import PublishedValues, plotted
from sniffer.exports.rerun_rows import EntityRows
from sniffer.exports.rerun_sdk import rr, rrb

APPLICATION = "rtusniff"
#: Live: how often what was buffered goes to the viewer (a quarter of a second behind the bus:
#: each entity sent is a fixed cost in the SDK, so sending more often costs a core on a busy line).
LIVE_SEND_S = 0.5
MAX_UNNAMED_SERIES = 64
#: Series (plot and state entities) kept by slave, address, code and unit.
KEPT_SERIES = 8192
SECOND_NS = 1_000_000_000
#: Rerun's level names by foxglove.Log level.
_LEVEL_NAMES = np.array([{INFO: "INFO", WARNING: "WARN", ERROR: "ERROR"}.get(level, "") for level in range(ERROR + 1)],
                        dtype=object)
_ERRORS = ("crc", "timeout", "exception")
# Read from every frame's parts with ``map``, in C.
_TEXT, _LATENCY_ENTITY = attrgetter("text"), attrgetter("latency_entity")
_SCALAR_IDS, _SCALAR_VALUES = attrgetter("scalar_ids"), attrgetter("scalar_values")
_EXCEPTION = ROLE_CODE[Role.EXCEPTION]


@dataclass(eq=False)
class _Parts:
    """What one decoding puts on the timeline: its log text, numeric params (entity ids and
    values), states (entity id, text) and its latency series (entity id, or -1)."""

    text: str
    scalar_ids: npt.NDArray[np.int64]
    scalar_values: npt.NDArray[np.float64]
    states: list[tuple[int, str]]
    latency_entity: int


def spawn_viewer(port: int, program: str | None) -> str:
    """Start a Rerun viewer (``program``) listening on ``port``; its address."""
    rr.spawn(port=port, connect=False, executable_path=program)
    return f"rerun+http://127.0.0.1:{port}/proxy"


class RerunExporter:
    """Buffers rows per entity and sends them in columns; ``close`` writes the file.

    Entities have integer ids, so that a batch's rows are sorted to their entities in columns:
    the per-frame Python work is looking up what its decoding contributes."""

    def __init__(self, path: str | None, viewer: str | None = None, *, live: bool = False) -> None:
        """``path``: an ``.rrd`` file to write; ``viewer``: the gRPC address of a Rerun viewer to
        stream to (both at once: one recording, two sinks). ``live``: every batch is sent at
        once (a viewer watching a bus), not gathered into large columns (a file)."""
        self._rec = rr.RecordingStream(APPLICATION)
        self._rec.set_log_time_enabled(False)
        self._rec.set_log_tick_enabled(False)
        self._live = live
        sinks: list[rr.GrpcSink | rr.FileSink] = []
        if viewer is not None:
            sinks.append(rr.GrpcSink(viewer))
        if path is not None:
            sinks.append(rr.FileSink(path))
        self._rec.set_sinks(*sinks)
        self.entities = EntityRows(self._rec, live=live)
        self._states: dict[int, str] = {}
        self._slaves: set[int] = set()
        self._published: PublishedValues[_Parts] = PublishedValues()
        #: (plot entity, state entity), or () for a register not plotted.
        self._param_entities: Memo[tuple[int, int, str | None, str | None], tuple[int, int] | tuple[()]] = Memo(
            KEPT_SERIES)
        #: Per slave address: the entity ids of its log and its crc, timeout and exception errors.
        self._slave_ids = np.full((256, 1 + len(_ERRORS)), -1, np.int64)
        self._unnamed: dict[int, set[int]] = {}
        self._second: int | None = None
        self._wire_ns = 0
        self._errors = 0
        #: Slaves in the blueprint sent last, and when the buffers go next (live).
        self._blueprint_slaves = -1
        self._next_live_send = 0.0

    def messages(self, batch: AnnotatedBatch) -> None:
        positions = np.asarray(batch.positions(), np.int64)
        if not len(positions):
            return
        messages, frames = batch.messages, batch.messages.frames
        t_start = frames.t_start_ns[positions]
        failed = errors(messages)[positions]
        self._bus(t_start, frames.t_end_ns[positions] - t_start, failed, first_index=frames.first_index)
        slave = messages.slave[positions]
        noise = slave == NONE
        if noise.any():
            chosen, summaries = positions[noise], batch.summaries()
            self.entities.append(self.entities.entity("bus/noise"), t_start[noise], chosen + frames.first_index,
                         texts=_strings([summaries[row] for row in np.flatnonzero(noise).tolist()]), level="WARN")
            keep = ~noise
            positions, t_start, slave = positions[keep], t_start[keep], slave[keep]
        if len(positions):
            self._frames(batch, positions, t_start, slave)
        if self._live:
            self._send_live()
        else:
            self.entities.send_due()

    def _send_live(self) -> None:
        """Everything buffered, at most every ``LIVE_SEND_S`` (each entity sent is a call into the
        SDK), and the blueprint again when a slave appeared (its plot)."""
        if time.monotonic() < self._next_live_send:
            return
        self._next_live_send = time.monotonic() + LIVE_SEND_S
        slaves = len(self._slaves)
        self.entities.flush()
        if slaves != self._blueprint_slaves:
            self._rec.send_blueprint(self.blueprint(), make_active=True)
            self._blueprint_slaves = slaves

    def _frames(self, batch: AnnotatedBatch, positions: npt.NDArray[np.int64], t_start: npt.NDArray[np.int64],
                slave: npt.NDArray[np.int16]) -> None:
        """The frames of slaves: log lines, parameter values, states, latencies, error points."""
        messages, frames = batch.messages, batch.messages.frames
        index = positions + frames.first_index
        for unknown in distinct(slave[self._slave_ids[slave, 0] < 0]).tolist():
            self._known_slave(unknown)
        parts = self._parts_of(batch, positions)
        flags = messages.flags[positions]
        texts = np.array(list(map(_TEXT, parts)), dtype=object)
        for row in np.flatnonzero(flags).tolist():
            texts[row] += FLAG_SUFFIXES[flags[row]]
        levels = _LEVEL_NAMES[log_levels(messages)[positions]]
        self.entities.grouped(self._slave_ids[slave, 0], t_start, index, texts=texts, levels=levels)
        self._values(self._published_parts(batch, positions, parts, slave), t_start, index)
        latency = messages.latency_ns[positions]
        crc_ok = frames.crc_ok[positions]
        latency_ids = np.fromiter(map(_LATENCY_ENTITY, parts), np.int64, len(parts))
        timed = (latency != NONE) & crc_ok & (latency_ids >= 0)
        self.entities.grouped(latency_ids[timed], t_start[timed], index[timed], values=latency[timed] / 1e6)
        failures = (~crc_ok, (flags & TIMEOUT) != 0, messages.role[positions] == _EXCEPTION)
        for column, failed in enumerate(failures, start=1):
            if failed.any():
                ids = self._slave_ids[slave[failed], column]
                self.entities.grouped(ids, t_start[failed], index[failed], values=np.ones(len(ids)))

    def _published_parts(self, batch: AnnotatedBatch, positions: npt.NDArray[np.int64], parts: list[_Parts],
                         slave: npt.NDArray[np.int16]) -> list[tuple[int, _Parts]]:
        """``(row, parts)`` whose values go on plots and state series: valid answers, and the
        writes they accept (:mod:`sniffer.exports.published`), in row order."""
        # What a write request puts on plots is what its own parts hold: the values it wrote.
        published, accepted = self._published.select(batch, positions, parts.__getitem__)
        shown = [(row, parts[row]) for row in np.flatnonzero(published).tolist()]
        if accepted:
            shown += accepted
            shown.sort(key=itemgetter(0))
        return shown

    def _values(self, shown: list[tuple[int, _Parts]], t_start: npt.NDArray[np.int64],
                index: npt.NDArray[np.int64]) -> None:
        """Parameter values as points of their plots, state texts when they change."""
        if not shown:
            return
        rows, parts = np.array([row for row, _ in shown], np.int64), [part for _, part in shown]
        counts = np.fromiter(map(len, map(_SCALAR_IDS, parts)), np.int64, len(parts))
        if counts.any():
            repeated = np.repeat(rows, counts)
            self.entities.grouped(np.concatenate(list(map(_SCALAR_IDS, parts))), t_start[repeated], index[repeated],
                          values=np.concatenate(list(map(_SCALAR_VALUES, parts))))
        for row, part in shown:
            for entity, text in part.states:
                if self._states.get(entity) != text:
                    self._states[entity] = text
                    # Copies, not views: a state can stay buffered all day, and a view would keep
                    # its whole batch's column alive with it.
                    self.entities.append(entity, t_start[[row]], index[[row]], texts=_strings([text]), level="INFO")

    def _parts_of(self, batch: AnnotatedBatch, positions: npt.NDArray[np.int64]) -> list[_Parts]:
        """The parts of the frames at ``positions`` (kept, none of them noise), made once per frame
        the decoded form gives (:meth:`AnnotatedBatch.columns`), in the order frames first appear
        (so that series are made in the order of the capture)."""
        messages, parts = batch.messages, batch.columns()
        made: list[list[_Parts | None]] = [[None] * len(part.spelt_positions) for part in parts]
        params, summaries = [part.spelt_param_values() for part in parts], [part.spelt_summaries() for part in parts]
        given = sorted((first, place, row) for place, part in enumerate(parts)
                       for row, first in enumerate(part.spelt_positions.tolist()))
        for first, place, row in given:
            slave, role, function = (int(column[first]) for column in (messages.slave, messages.role,
                                                                        messages.function))
            if slave != NONE:
                made[place][row] = self._frame_parts(params[place][row], summaries[place][row], slave, role, function)
        by_part = {id(part): rows for part, rows in zip(parts, made, strict=True)}
        every = batch.each_message(lambda part: part.each(by_part[id(part)]))
        # None of ``positions`` is noise: each one's parts were made.
        return cast("list[_Parts]", batch.kept_at(every, positions))

    def _frame_parts(self, params: Params, summary: str, slave: int, role: int, function: int) -> _Parts:
        """What a frame of ``slave`` that names ``params`` puts on the timeline."""
        self._known_slave(slave)
        scalar_ids: list[int] = []
        scalar_values: list[float] = []
        states: list[tuple[int, str]] = []
        for param in plotted(params):
            series = self._param_series(slave, param)
            if not series:
                continue
            if isinstance(param.value, int | float):
                scalar_ids.append(series[0])
                scalar_values.append(float(param.value))
            elif isinstance(param.value, str) and param.code is not None:
                states.append((series[1], f"{param.code}: {param.value}"))
        latency = -1
        if function != NONE:
            latency = self.entities.entity(f"slaves/{slave}/latency_ms/fc{function}", f"latency FC {function} (ms)")
        return _Parts(f"{ROLE_NAMES[role]}: {summary}", np.array(scalar_ids, np.int64),
                      np.array(scalar_values, np.float64), states, latency)

    def _known_slave(self, slave: int) -> None:
        if slave not in self._slaves:
            self._slaves.add(slave)
            entity = self.entities.entity
            self._slave_ids[slave] = [
                entity(f"slaves/{slave}/log"),
                *(entity(f"slaves/{slave}/errors/{kind}", f"{kind} errors", points=True) for kind in _ERRORS),
            ]

    def _param_series(self, slave: int, param: ParamValue) -> tuple[int, int] | tuple[()]:
        """A parameter's plot entity and its state entity; none for an unnamed register past the
        first ``MAX_UNNAMED_SERIES`` of its slave. Kept: slaves are polled for the same
        parameters all day."""
        key = (slave, param.address, param.code, param.unit)
        known = self._param_entities.get(key)
        if known is not None:
            return known
        code = param.code or str(param.address)
        series: tuple[int, int] | tuple[()] = ()
        if param.code is not None or self._may_plot(slave, param.address):
            name = f"{code} ({param.unit})" if param.unit else code
            series = (self.entities.entity(f"slaves/{slave}/params/{_path(code)}", name),
                      self.entities.entity(f"slaves/{slave}/state/{_path(code)}"))
        self._param_entities.put(key, series)
        return series

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
        seconds = t_start // SECOND_NS
        starts = np.flatnonzero(np.diff(seconds, prepend=seconds[0] - 1))
        wire = np.add.reduceat(wire_ns, starts).tolist()
        failures = np.add.reduceat(failed.astype(np.int64), starts).tolist()
        times, indexes, loads, rates = [], [], [], []
        for second, first, wire_sum, error_count in zip(seconds[starts].tolist(), starts.tolist(), wire, failures,
                                                         strict=True):
            if self._second is not None and second != self._second:
                times.append(self._second * SECOND_NS)
                indexes.append(first_index + first)
                loads.append(100 * self._wire_ns / SECOND_NS)
                rates.append(float(self._errors))
                self._wire_ns = self._errors = 0
            self._second = second
            self._wire_ns += wire_sum
            self._errors += error_count
        if times:
            at, frame, entities = np.array(times, np.int64), np.array(indexes, np.int64), self.entities
            entities.append(entities.entity("bus/load_percent", "bus load (%)"), at, frame, values=np.array(loads))
            entities.append(entities.entity("bus/errors_per_s", "errors per second"), at, frame, values=np.array(rates))

    @property
    def skipped_rows(self) -> int:
        """Live: rows not sent because the SDK fell behind (the recording has them)."""
        return self.entities.skipped_rows

    def close(self) -> None:
        self.entities.close()
        self._rec.send_blueprint(self.blueprint())
        self._rec.flush()
        self._rec.disconnect()

    def abandon(self) -> None:
        """The viewer went away: stop sending, wait for nothing, keep no error of it."""
        self.entities.abandon()
        with contextlib.suppress(Exception):  # the SDK's errors for a connection that is gone
            self._rec.disconnect()

    def blueprint(self) -> rrb.Blueprint:
        """Plots on top (one per slave, and the bus), logs below."""
        plots = [rrb.TimeSeriesView(origin=f"/slaves/{slave}", name=f"slave {slave}") for slave in sorted(self._slaves)]
        plots.append(rrb.TimeSeriesView(origin="/bus", name="bus"))
        return rrb.Blueprint(
            rrb.Vertical(rrb.Grid(*plots), rrb.TextLogView(origin="/", name="frames"), row_shares=[3, 2]),
            rrb.TimePanel(expanded=True),
        )


def _strings(texts: list[str]) -> npt.NDArray[np.object_]:
    strings: npt.NDArray[np.object_] = np.array(texts, dtype=object)
    return strings


def _path(code: str) -> str:
    """An entity path part from a parameter code (``NM1→ETA`` → ``NM1_ETA``)."""
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in code)

