"""``rtusniff values``: every value a slave reported or was written, over time.

A row per value (long form, :mod:`sniffer.encoding.value_rows` finds them): the frame's time and
index, the slave, whether the value was ``reported`` or ``written``, the register's address, the
profile's code, name and unit, the raw word, the value as the device means it, the request the
row belongs to, and ``valid``.

``--changes`` keeps a row only when its value differs from the last one of the same slave,
address and kind; ``--wide`` writes one row per frame with a column per parameter instead (the
rows are held until the end, to know every column).
"""

from __future__ import annotations

import csv
import json
from datetime import UTC, datetime
from typing import Any, TextIO

import numpy as np

from decoders.capture import CaptureInfo
from decoders.line import LineSettings
from decoders.memo import KeptByIdentity
from decoders.message import ParamValue
from decoders.stats import Statistics
from sniffer.encoding.param_text import json_value
from sniffer.encoding.value_rows import ValueChoice, ValueRow, ValueRows
from sniffer.errors import ErrorKind, RtuSniffError

LONG_COLUMNS = ("time", "t_ns", "index", "slave", "kind", "address", "code", "name", "raw", "value", "unit",
                "request_index", "valid")
WIDE_FIXED = ("time", "t_ns", "index", "slave", "kind")
#: The columns of :data:`LONG_COLUMNS` a param fills.
_PARAM_COLUMNS = ("address", "code", "name", "raw", "value", "unit")
#: ``--wide`` holds every value until the end, and its CSV has a cell for every row and column:
#: beyond these it is refused with the figures (a 3.5 MB capture once made 4.4 GB of CSV).
MAX_WIDE_VALUES = 20_000_000
MAX_WIDE_CELLS = 100_000_000


class ValuesView(ValueRows):
    """Writes the rows (see the module docstring) as CSV or JSON Lines."""

    def __init__(self, out: TextIO, choice: ValueChoice, *, as_json: bool, wide: bool, time_mode: str) -> None:
        super().__init__(choice)
        self._out, self._json, self._wide, self._mode = out, as_json, wide, time_mode
        #: ``--time relative`` counts from the first frame read.
        self._origin_ns: int | None = None
        self._csv = csv.writer(out, lineterminator="\n")
        self._held: list[tuple[ValueRow, int]] = []
        self._held_values = 0
        #: The CSV cells of each param (address to unit), by its identity (frames alike share
        #: their params, a namer its values).
        self._param_cells: KeptByIdentity[ParamValue, list[object]] = KeptByIdentity(_param_cells)
        #: The second :meth:`_time` last wrote, and its text before and after the microseconds.
        self._second: int | None = None
        self._second_texts = ("", "")

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        if not self._json and not self._wide:
            self._csv.writerow(LONG_COLUMNS)

    def _first_frame(self, t_start_ns: object) -> None:
        if self._origin_ns is None and isinstance(t_start_ns, np.ndarray) and len(t_start_ns):
            self._origin_ns = int(t_start_ns[0])

    def output(self, row: ValueRow) -> None:
        if self._wide:
            self._held.append((row, len(self._held)))
            self._held_values += len(row.params)
            if self._held_values > MAX_WIDE_VALUES:
                raise RtuSniffError(ErrorKind.USAGE, f"--wide holds every value until the end, and this capture has "
                                    f"more than {MAX_WIDE_VALUES:,}: write the long form (without --wide), or choose "
                                    "fewer with --slave, --param or --changes")
        elif self._json:
            self._out.write("".join(json.dumps(record, ensure_ascii=False) + "\n" for record in self._records(row)))
        else:
            self._csv.writerows(self._csv_rows(row))

    def _csv_rows(self, row: ValueRow) -> list[list[object]]:
        """The rows' CSV cells (what :meth:`_records` holds, each as :func:`_cell` writes it), a
        param's cells made once."""
        fixed, request = self._fixed(row), _cell(row.request_index)
        return [[*fixed, *cells, request, "true" if valid else "false"]
                for cells, valid in zip(self._param_cells.made(list(row.params)), row.valid, strict=True)]

    def _records(self, row: ValueRow) -> list[dict[str, Any]]:
        time = self._time(row.t_ns)
        return [{"time": time, "t_ns": row.t_ns, "index": row.index, "slave": row.slave, "kind": row.kind,
                 "address": p.address, "code": p.code, "name": p.name, "raw": p.raw, "value": json_value(p.value),
                 "unit": p.unit, "request_index": row.request_index, "valid": valid}
                for p, valid in zip(row.params, row.valid, strict=True)]

    def finish(self, statistics: Statistics) -> None:
        super().finish(statistics)
        if self._wide:
            self._write_wide()
        self._out.flush()

    def _write_wide(self) -> None:
        """A row per frame, a column per parameter (``SLAVE:CODE``, or ``SLAVE:ADDRESS``)."""
        held = sorted(self._held, key=lambda item: (item[0].t_ns, item[1]))
        names: dict[str, None] = {}
        for row, _ in held:
            for param in row.params:
                names[_column(row.slave, param)] = None
        order = sorted(names, key=_column_order)
        if self._json:
            for row, _ in held:
                record = {**{name: value for name, value in zip(WIDE_FIXED, self._fixed(row), strict=True)},
                          **{_column(row.slave, p): json_value(p.value) for p in row.params}}
                self._out.write(json.dumps(record, ensure_ascii=False) + "\n")
            return
        cells = len(held) * (len(WIDE_FIXED) + len(order))
        if cells > MAX_WIDE_CELLS:
            raise RtuSniffError(ErrorKind.USAGE, f"--wide would write {len(held):,} rows of {len(order):,} parameters "
                                f"({cells:,} cells, most of them empty): over the {MAX_WIDE_CELLS:,} it writes; choose "
                                "fewer with --slave, --param or --changes, or write the long form or --format jsonl")
        self._csv.writerow([*WIDE_FIXED, *order])
        for row, _ in held:
            values = {_column(row.slave, p): p.value for p in row.params}
            self._csv.writerow([*map(_cell, self._fixed(row)), *(_cell(values.get(name)) for name in order)])

    def _fixed(self, row: ValueRow) -> list[object]:
        return [self._time(row.t_ns), row.t_ns, row.index, row.slave, row.kind]

    def _time(self, t_ns: int) -> str:
        """ISO 8601 with microseconds (``Z`` for UTC, the offset for local time), or seconds since
        the first frame read (``relative``): what a spreadsheet or pandas reads as a time."""
        if self._mode == "relative":
            return f"{(t_ns - (self._origin_ns or t_ns)) // 1000 / 1e6:.6f}"
        seconds, nanos = divmod(t_ns, 1_000_000_000)
        if seconds != self._second:  # the date and time of a second, made once for its frames
            moment = datetime.fromtimestamp(seconds, UTC)
            if self._mode == "local":
                head, _, offset = moment.astimezone().isoformat(timespec="microseconds").partition(".")
                self._second_texts = (head + ".", offset[6:])
            else:
                self._second_texts = (moment.strftime("%Y-%m-%dT%H:%M:%S."), "Z")
            self._second = seconds
        head, tail = self._second_texts
        return f"{head}{nanos // 1000:06d}{tail}"


def _param_cells(param: ParamValue) -> list[object]:
    """A param's CSV cells, address to unit."""
    return [_cell(getattr(param, name)) for name in _PARAM_COLUMNS]


def _column(slave: int, param: ParamValue) -> str:
    return f"{slave}:{param.code if param.code is not None else param.address}"


def _column_order(name: str) -> tuple[int, str]:
    slave, _, what = name.partition(":")
    return int(slave), what


def _cell(value: object) -> object:
    """A CSV cell: empty for none, ``true``/``false`` for booleans (as JSON writes them)."""
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    return value
