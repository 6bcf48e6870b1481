"""Rows on their way to Rerun: buffered per entity, sent in columns (``send_columns``).

Sending column by column is hundreds of times faster than logging row by row. Each send is one
chunk, and the recording keeps an index entry per chunk until it writes the file's footer, so an
entity is sent when it holds ``ENTITY_ROWS`` rows, and only when all buffers together pass
``MAX_BUFFERED_ROWS`` are the largest ones sent early: a day-long capture makes a few thousand
large chunks, not one per entity and batch, and memory stays flat. Live (a viewer watching a
bus), everything buffered goes at once to a sending thread (:class:`LiveSender`).

Entities have integer ids, so that a batch's rows are sorted to their entities in columns.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from sniffer.exports.rerun_live import LiveSender
from sniffer.exports.rerun_sdk import rr

ENTITY_ROWS = 32_768
MAX_BUFFERED_ROWS = 400_000
#: Column pieces an entity's buffer holds before they are merged into one.
MAX_PIECES = 32
#: Live: a flush (which finds a viewer gone) every this many rounds, and how long it may wait
#: for a slow viewer.
FLUSH_EVERY_ROUNDS = 4
LIVE_FLUSH_S = 5.0
#: A series' style: a line of values, or points (one for each error).
Style = rr.SeriesLines | rr.SeriesPoints


@dataclass
class Rows:
    """Buffered rows of one entity, as the column pieces of each batch."""

    times: list[npt.NDArray[np.int64]] = field(default_factory=list)
    frames: list[npt.NDArray[np.int64]] = field(default_factory=list)
    values: list[npt.NDArray[np.float64]] = field(default_factory=list)
    #: Text logs' rows as object arrays of str: Rerun hands those to Arrow as they are, where it
    #: would call ``str`` on every item of a list.
    texts: list[npt.NDArray[np.object_]] = field(default_factory=list)
    levels: list[npt.NDArray[np.object_]] = field(default_factory=list)
    count: int = 0

    def merge(self) -> None:
        """One piece per column: a slave's rarely read parameter gains a row or two a batch, and
        an array per row would cost a hundred bytes of header for its eight of data."""
        for pieces in (self.times, self.frames, self.values, self.texts, self.levels):
            if len(pieces) > 1:
                pieces[:] = [np.concatenate(pieces)]


def send_rows(rec: rr.RecordingStream, path: str, style: Style | None, rows: Rows) -> None:
    """One entity's buffered rows as columns (its series style first, once)."""
    if rows.texts:
        columns = rr.TextLog.columns(text=np.concatenate(rows.texts), level=np.concatenate(rows.levels))
    else:
        columns = rr.Scalars.columns(scalars=np.concatenate(rows.values))
    indexes = [
        rr.TimeColumn("capture_time", timestamp=np.concatenate(rows.times).astype("datetime64[ns]")),
        rr.TimeColumn("frame", sequence=np.concatenate(rows.frames)),
    ]
    if style is not None:
        rec.log(path, style, static=True)
    rec.send_columns(path, indexes=indexes, columns=columns)


class EntityRows:
    """Every entity's id and path, and its rows until they are sent to ``rec``."""

    def __init__(self, rec: rr.RecordingStream, *, live: bool) -> None:
        self._rec = rec
        #: Live: the thread that sends, so that the decoding never waits for the SDK.
        self._sender = LiveSender(self._send_round) if live else None
        self._rounds_sent = 0
        self.paths: list[str] = []
        self._ids: dict[str, int] = {}
        #: Series styles of plotted entities not sent yet.
        self._styles: dict[int, Style] = {}
        self.buffers: dict[int, Rows] = {}
        #: Rows buffered, all entities together.
        self.rows = 0

    def entity(self, path: str, series: str | None = None, *, points: bool = False) -> int:
        """An entity's id; a plotted one (``series`` named) gets its style, as static data, with
        its first rows: an entity that never gets any is not shown as an empty series."""
        entity = self._ids.get(path)
        if entity is None:
            entity = self._ids[path] = len(self.paths)
            self.paths.append(path)
            if series is not None:
                self._styles[entity] = rr.SeriesPoints(names=series) if points else rr.SeriesLines(names=series)
        return entity

    def grouped(self, entities: npt.NDArray[np.int64], times: npt.NDArray[np.int64], frames: npt.NDArray[np.int64],
                *, values: npt.NDArray[np.float64] | None = None, texts: npt.NDArray[np.object_] | None = None,
                levels: npt.NDArray[np.object_] | None = None) -> None:
        """Rows of several entities, each given to its entity in its order."""
        if not len(entities):
            return
        order = np.argsort(entities, kind="stable")
        ordered = entities[order]
        starts = np.flatnonzero(np.diff(ordered, prepend=ordered[0] - 1))
        for entity, rows in zip(ordered[starts].tolist(), np.split(order, starts[1:]), strict=True):
            if texts is not None and levels is not None:
                self.append(entity, times[rows], frames[rows], texts=texts[rows], levels=levels[rows])
            elif values is not None:
                self.append(entity, times[rows], frames[rows], values=values[rows])

    def append(self, entity: int, times: npt.NDArray[np.int64], frames: npt.NDArray[np.int64], *,
               values: npt.NDArray[np.float64] | None = None, texts: npt.NDArray[np.object_] | None = None,
               level: str = "INFO", levels: npt.NDArray[np.object_] | None = None) -> None:
        rows = self.buffers.get(entity)
        if rows is None:
            rows = self.buffers[entity] = Rows()
        rows.times.append(times)
        rows.frames.append(frames)
        if values is not None:
            rows.values.append(values)
        if texts is not None:
            rows.texts.append(texts)
            rows.levels.append(levels if levels is not None else np.full(len(texts), level, dtype=object))
        rows.count += len(times)
        self.rows += len(times)
        if len(rows.times) >= MAX_PIECES:
            rows.merge()

    def send_due(self) -> None:
        """Send full entities; past the memory cap, send the largest until half the cap is left."""
        for entity, rows in list(self.buffers.items()):
            if rows.count >= ENTITY_ROWS:
                self._send(entity, rows)
        if self.rows < MAX_BUFFERED_ROWS:
            return
        for entity, rows in sorted(self.buffers.items(), key=lambda item: -item[1].count):
            if self.rows <= MAX_BUFFERED_ROWS // 2:
                break
            self._send(entity, rows)

    def _send(self, entity: int, rows: Rows) -> None:
        del self.buffers[entity]
        send_rows(self._rec, self.paths[entity], self._styles.pop(entity, None), rows)
        self.rows -= rows.count

    def flush(self) -> None:
        """Everything buffered: sent, or live handed over to the sending thread in one round."""
        if self._sender is not None:
            items = [(self.paths[entity], self._styles.pop(entity, None), rows)
                     for entity, rows in self.buffers.items()]
            self._sender.submit(items, self.rows)
            self.buffers, self.rows = {}, 0
            return
        for entity, rows in list(self.buffers.items()):
            self._send(entity, rows)

    def _send_round(self, items: list[tuple[str, Style | None, Rows]]) -> None:
        for path, style, rows in items:
            send_rows(self._rec, path, style, rows)
        # The SDK takes rows for a viewer that has gone and says so only when flushed: a flush
        # every few rounds raises at once where the connection broke (waited for here, in the
        # sending thread; each flush also sends what the SDK was batching, which costs CPU).
        self._rounds_sent += 1
        if self._rounds_sent % FLUSH_EVERY_ROUNDS:
            return
        try:
            self._rec.flush(timeout_sec=LIVE_FLUSH_S)
        except RuntimeError as exc:
            if "time" not in str(exc).lower():  # a slow viewer is not a gone one: its rounds get skipped
                raise

    @property
    def skipped_rows(self) -> int:
        """Live: rows not sent because the SDK fell behind (the recording has them)."""
        return self._sender.skipped_rows if self._sender is not None else 0

    def close(self) -> None:
        """Everything sent (live: once the sending thread has sent every round)."""
        self.flush()
        if self._sender is not None:
            self._sender.close()

    def abandon(self) -> None:
        """The viewer went away: the sending thread stops, waiting for nothing."""
        if self._sender is not None:
            self._sender.abandon()
