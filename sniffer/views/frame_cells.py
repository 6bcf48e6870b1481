"""The cells of the frame tables (``analyze``, the live view), built a column at a time from an
annotated batch: the numbers by one conversion per column, the rest by lookups."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from decoders.damage import crc_note, uart_error_note
from decoders.decoded_batch import AnnotatedBatch, remarked
from decoders.frame import _NAMES_BY_VALUE, NO_IDLE, FrameFlag
from decoders.message import NONE, ROLE_ORDER, Decoding, MessageBatch, Role
from sniffer.views.clock import Clock
from sniffer.views.layout import ALWAYS, Cells, Column

ROLE_STYLES = {
    Role.REQUEST: "cyan",
    Role.RESPONSE: "green",
    Role.EXCEPTION: "bold red",
    Role.BROADCAST: "magenta",
    Role.NOISE: "dim",
    Role.UNKNOWN: "yellow",
}
_ROLE_NAMES = [role.value for role in ROLE_ORDER]
#: On a narrow terminal (under ``NARROW`` columns) roles are abbreviated, to leave the summary room.
_SHORT_ROLES = {"request": "req", "response": "resp", "exception": "exc", "broadcast": "bcast", "noise": "noise",
                "unknown": "unk"}
_SHORT_ROLE_NAMES = [_SHORT_ROLES[name] for name in _ROLE_NAMES]
NARROW = 100
_ROLE_STYLE_LIST = [ROLE_STYLES[role] for role in ROLE_ORDER]
_NOISE = ROLE_ORDER.index(Role.NOISE)
#: Flag names per flag value, as the terminal (spaces: wraps) and a pipe (commas: one field) write them.
_FLAGS_SPACED = [" ".join(names) for names in _NAMES_BY_VALUE]
_FLAGS_JOINED = [",".join(names) for names in _NAMES_BY_VALUE]

#: Summary of a decoding in a table cell: its own summary, or the ``--registers`` reading of it.
SummaryOf = Callable[[Decoding], str]


def frame_columns(clock: Clock, *, plain: bool, hex_shown: bool | None, live: bool = False) -> list[Column]:
    """The columns of a frame table. ``hex_shown``: ``True`` always (``--hex``), ``None`` when
    there is room (a terminal), ``False`` never. What matters (index, time, Δt, slave, function,
    role, CRC, flags, summary) is never dropped; request, latency and length go first, then hex.
    The ``live`` view keeps the latency instead of Δt (between host reads, it says little)."""
    columns = [
        Column("index", "#", right=True),
        Column("time", clock.header),
        Column("idle", "Δt ms", right=True, keep=25 if live else ALWAYS),
        Column("slave", "slave", right=True),
        Column("function", "fc", right=True),
        Column("role", "role"),
        Column("request", "req", right=True, keep=20),
        Column("latency", "lat ms", right=True, keep=ALWAYS if live else 30),
        Column("length", "len", right=True, keep=10),
        Column("crc", "CRC"),
        # As wide as the longest flag (short_idle, unexpected, uart_error): a flag is never split.
        Column("flags", "flags", flexible=True, min_width=10, max_width=18),
    ]
    summary = Column("summary", "summary", flexible=True, min_width=20)
    hex_column = Column("hex", "hex", flexible=True, keep=ALWAYS if hex_shown else 5, min_width=23, max_width=47)
    if plain:
        # One field per column for awk: the summary, with its spaces, last.
        return columns + ([hex_column] if hex_shown else []) + [summary]
    return columns + [summary] + ([hex_column] if hex_shown is not False else [])


def frame_cells(messages: MessageBatch, rows: npt.NDArray[np.int64], clock: Clock, *, plain: bool,
                styled: bool, short_roles: bool = False, latencies: list[str] | None = None) -> dict[str, Cells]:
    """The cells of every column but the summary for the messages of ``messages`` at ``rows``
    (``latencies``: the latency column's texts, if not the published latencies). Needs no
    decoding: it may run where the frames are paired (a sink's ``prepare``)."""
    frames = messages.frames
    role_codes = messages.role[rows].tolist()
    crc_ok = frames.crc_ok[rows].tolist()
    noise = [code == _NOISE for code in role_codes]
    offsets = frames.offsets
    lengths = (offsets[rows + 1] - offsets[rows]).tolist()
    flag_names = _FLAGS_JOINED if plain else _FLAGS_SPACED
    return {
        "index": Cells(list(map(str, (rows + frames.first_index).tolist()))),
        "time": Cells(clock.texts(frames.t_start_ns[rows])),
        "idle": Cells(_milliseconds(frames.idle_before_ns[rows], NO_IDLE)),
        "slave": Cells(_integers(messages.slave[rows])),
        "function": Cells(_integers(messages.function[rows])),
        "role": Cells([(_SHORT_ROLE_NAMES if short_roles else _ROLE_NAMES)[code] for code in role_codes],
                      [_ROLE_STYLE_LIST[code] for code in role_codes] if styled else None),
        "request": Cells(_blank(list(map("#%d".__mod__, messages.request_index[rows].tolist())),
                                messages.request_index[rows] == NONE)),
        "latency": Cells(latencies if latencies is not None else _milliseconds(messages.latency_ns[rows], NONE)),
        "length": Cells(list(map(str, lengths))),
        "crc": Cells(["" if n else ("ok" if ok else "BAD") for ok, n in zip(crc_ok, noise, strict=True)],
                     ["" if ok else "bold red" for ok in crc_ok] if styled else None),
        "flags": Cells([flag_names[value] for value in messages.flags[rows].tolist()],
                       ["yellow"] * len(rows) if styled else None),
        "hex": Cells(_hex(frames.data, offsets, rows, spaced=not plain)),
    }


def kept_rows(batch: AnnotatedBatch) -> npt.NDArray[np.int64]:
    return np.arange(len(batch.decoded), dtype=np.int64) if batch.rows is None else batch.rows


def frame_notes(messages: MessageBatch, rows: npt.NDArray[np.int64], retries: dict[int, str]) -> dict[int, str]:
    """What the summary of a frame at ``rows`` adds after its own, by position: a damaged frame's
    CRC, the characters the receiver found wrong, a good retry's difference (``retries``).
    Needs no decoding."""
    frames, notes = messages.frames, {}
    broken = np.flatnonzero(~frames.crc_ok[rows] & (messages.role[rows] != _NOISE))
    positions = set(rows[broken].tolist()) | (set(retries) & set(rows.tolist()))
    if frames.uart_errors is not None:
        positions |= set(rows[np.flatnonzero(frames.flags[rows] & FrameFlag.UART_ERROR)].tolist())
    frame_rows = frames.rows()
    for position in sorted(positions):
        extra = []
        if not frames.crc_ok[position] and messages.role[position] != _NOISE:
            note = crc_note(frames.data[frames.offsets[position] : frames.offsets[position + 1]])
            if note:
                extra.append(note)
        if frames.flags[position] & FrameFlag.UART_ERROR:
            extra.append(uart_error_note(frame_rows[position].uart_errors))
        if position in retries:
            extra.append(retries[position])
        if extra:
            notes[position] = "".join(f" ⚠ {text}" for text in extra)
    return notes


def summary_cells(batch: AnnotatedBatch, rows: npt.NDArray[np.int64], summary_of: SummaryOf,
                  notes: dict[int, str]) -> Cells:
    """The summary of the messages at ``rows`` with ``notes`` (:func:`frame_notes`) after them."""
    if summary_of is decoding_summary:  # the decoded form's lines, not an object per frame
        texts = batch.kept_at(batch.remarked_summaries(), rows)
    else:
        texts = list(map(summary_of, batch.decodings_at(rows.tolist())))
    if notes:
        for row, position in enumerate(rows.tolist()):
            if position in notes:
                texts[row] += notes[position]
    return Cells(texts)


def _integers(column: npt.NDArray[np.integer]) -> list[str]:
    texts = list(map(str, column.tolist()))
    return _blank(texts, column == NONE)


def _milliseconds(column: npt.NDArray[np.int64], none: int) -> list[str]:
    """``12.345``: milliseconds with three decimals, from whole microseconds (``%`` in C, per row)."""
    empty = column == none
    micros = (np.where(empty, 0, column) + 500) // 1000  # to the nearest microsecond
    texts = list(map("%d.%03d".__mod__, zip((micros // 1000).tolist(), (micros % 1000).tolist(), strict=True)))
    return _blank(texts, empty)


def _blank(texts: list[str], empty: npt.NDArray[np.bool_]) -> list[str]:
    for row in np.flatnonzero(empty).tolist():
        texts[row] = ""
    return texts


def _hex(data: bytes, offsets: npt.NDArray[np.int64], rows: npt.NDArray[np.int64], *, spaced: bool) -> list[str]:
    text = data.hex(" ") if spaced else data.hex()
    step = 3 if spaced else 2
    trim = 1 if spaced else 0
    starts, ends = (offsets[rows] * step).tolist(), (offsets[rows + 1] * step - trim).tolist()
    return [text[s:e] for s, e in zip(starts, ends, strict=True)]


def decoding_summary(decoding: Decoding) -> str:
    """The decoding's summary with the device profile's remarks."""
    return remarked(decoding.summary, decoding.remarks)
