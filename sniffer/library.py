"""rtusniff as a library: a capture opened in Python, its decoded tables as Arrow tables.

    import sniffer
    capture = sniffer.open_capture("captures/atv71-plc-poll.log", profile="atv71")
    capture.table("transactions").to_pandas()

:func:`open_capture` takes the options of the command line, by their names there (``line="19200
8E1"``, ``profile=["2=atv71"]``, ``start="90s"``, ``registers="f32:little"``), and reads them as
the command line does, so that a capture decodes in Python as it does in ``rtusniff export``: the
tables are the ones ``export --parquet`` writes (:data:`TABLES`), row for row, with their schema
and metadata, made by the same sink (:class:`sniffer.exports.outputs.ParquetSink`, held in
memory). Decoding runs once, when a table, the statistics or the findings are first asked for;
:meth:`Capture.frames` decodes again, for the frames as objects. Errors are
the command line's (:class:`~sniffer.errors.RtuSniffError`, whose ``kind`` is the exit code's).
"""

from __future__ import annotations

import argparse
import html
import importlib
import os
from collections.abc import Iterator, Sequence
from contextlib import ExitStack
from datetime import datetime
from typing import TYPE_CHECKING, Any, NamedTuple, NoReturn

from decoders.decoded_batch import AnnotatedBatch
from decoders.message import Message
from sniffer.cli import OneLineParser, build_parser
from sniffer.commands.common import add_decoding_options, capture_paths, open_analysis, source_name
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports import TABLES
from sniffer.pipeline import Analysis, analyze
from sniffer.sinks import Sink

if TYPE_CHECKING:
    import pyarrow as pa

    from decoders.findings import Finding
    from decoders.stats import Statistics
    from sniffer.exports.parquet_export import ArrowTables


def open_capture(path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], **options: Any) -> Capture:
    """The capture at ``path`` (several paths: rotated files read as one), to be decoded with
    ``options``: the command line's decoding options by their names there (``--profile-file``:
    ``profile_file``), a value as the command line takes it, a list for an option it takes
    again and again; ``bus`` names the bus as ``export --bus`` does. The file is opened and its
    line settings settled at once: a bad option or file raises here."""
    paths = [os.fspath(path)] if isinstance(path, str | os.PathLike) else [os.fspath(each) for each in path]
    return Capture(_arguments(paths, options))


class _RaisingParser(OneLineParser):
    """The command line's parser, whose errors are raised, not printed."""

    def error(self, message: str) -> NoReturn:
        raise RtuSniffError(ErrorKind.USAGE, message)


def _arguments(paths: list[str], options: dict[str, Any]) -> argparse.Namespace:
    """``options`` read by ``export``'s parser, as the command line's would be."""
    parser = build_parser("export", _RaisingParser)
    actions = {action.dest: action for action in _decoding_actions(parser)}
    argv: list[str] = []
    for name, value in options.items():
        action = actions.get(name)
        if action is None:
            known = ", ".join(sorted(actions))
            raise RtuSniffError(ErrorKind.USAGE, f"open_capture: no option {name!r} (the options: {known})")
        argv += _option_argv(action, value)
    args = parser.parse_args(["export", *paths, *argv])
    args.command_line = ["rtusniff", "export", *paths, *argv]  # the tables' provenance: the command that decodes alike
    return args


def _decoding_actions(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options of ``export`` (the one command of ``parser``) that say how to decode, and
    ``--bus``."""
    wanted = _decoding_dests() | {"bus"}
    (export,) = [choice for action in parser._actions if isinstance(action, argparse._SubParsersAction)
                 for choice in action.choices.values()]
    return [action for action in export._actions if action.option_strings and action.dest in wanted]


def _decoding_dests() -> set[str]:
    """What :func:`~sniffer.commands.common.add_decoding_options` adds (not ``--help``)."""
    parser = argparse.ArgumentParser(add_help=False)
    add_decoding_options(parser)
    return {action.dest for action in parser._actions}


def _option_argv(action: argparse.Action, value: Any) -> list[str]:
    """``value`` of ``action`` as the command line spells it."""
    option = action.option_strings[-1]
    if isinstance(action, argparse._StoreTrueAction):
        return [option] if value else []
    values = list(value) if isinstance(value, list | tuple) else [value]
    if isinstance(action, argparse._AppendAction):
        return [part for each in values for part in (option, str(each))]
    if action.nargs not in (None, "?"):  # several words: "19200 8E1"
        return [option, *(word for each in values for word in str(each).split())]
    if len(values) != 1:
        raise RtuSniffError(ErrorKind.USAGE, f"open_capture: {action.dest} takes one value, not {len(values)}")
    return [option, str(values[0])]


class Transaction(NamedTuple):
    """A request and what became of it: a row of the ``transactions`` table
    (``docs/exports.md``)."""

    t: datetime
    t_ns: int
    request_index: int
    answer_index: int | None
    slave: int | None
    function: int | None
    #: ``answered``, ``exception``, ``crc_error``, ``timeout`` or ``broadcast``
    outcome: str
    exception_code: int | None
    latency_ms: float | None


class Capture:
    """A capture opened, and how to decode it (:func:`open_capture`): what every command of the
    command line decodes too, each into its own outputs (:meth:`decode`)."""

    def __init__(self, args: argparse.Namespace, stack: ExitStack | None = None) -> None:
        """``args``: the command line's; ``stack``: a command's, which closes the capture with its
        other files (else the capture closes itself after its first decoding, or at
        :meth:`close`). The capture is opened and its line settings settled here: a bad file or
        option is said at once."""
        self._args = args
        self._own: ExitStack | None = None
        if stack is None:
            stack = self._own = ExitStack()
        try:
            #: The capture's reader, opened; and how it is decoded (line, timing, profiles, window).
            self.reader, self.analysis = open_analysis(args, stack)
        except BaseException:
            self.close()
            raise
        #: What the file says of itself (format, line, timing, notes).
        self.info = self.reader.info
        #: The line settings it is decoded with.
        self.line = self.analysis.line
        self._read = False
        self._tables: ArrowTables | None = None
        self._statistics: Statistics | None = None
        self._findings: list[Finding] = []

    def decode(self, sinks: Sequence[Sink], *, jobs: int = 1, analysis: Analysis | None = None) -> Statistics:
        """Decodes the capture into ``sinks`` (:mod:`sniffer.sinks`; ``jobs=2``: in two
        processes; ``analysis``: decoded otherwise than :attr:`analysis`), and its statistics
        (counted where a sink wants them).
        The first time from the reader opened; again by opening the capture again (not
        standard input, which is read once)."""
        if not self._read:
            self._read = True
            try:
                return analyze(self.reader, self.source, analysis or self.analysis, sinks, jobs=jobs)
            finally:
                self.close()
        if "-" in capture_paths(self._args):
            raise RtuSniffError(ErrorKind.USAGE, "a capture read from standard input is decoded once")
        with ExitStack() as stack:
            reader, opened = open_analysis(self._args, stack)
            return analyze(reader, self.source, analysis or opened, sinks, jobs=jobs)

    def close(self) -> None:
        """Closes the capture's file, where the capture opened it itself."""
        if self._own is not None:
            self._own.close()

    def __enter__(self) -> Capture:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def source(self) -> str:
        """The capture's name as the command line says it (several files joined by ``+``)."""
        return source_name(self._args)

    def table(self, name: str, *, partitions: bool = False) -> pa.Table:
        """One of :data:`TABLES`, as ``export --parquet`` writes it for this capture: its file's
        schema and metadata, its rows in order; ``partitions``: with the dataset's ``bus`` and
        ``date`` (``YYYY-MM-DD``, UTC) last, as a reader of the dataset gets them."""
        if name not in TABLES:
            raise RtuSniffError(ErrorKind.USAGE, f"no table {name!r}; the tables: {', '.join(TABLES)}")
        held = self._held()
        table = held.tables[name]
        if not partitions:
            return table
        import numpy as np  # noqa: PLC0415 - loaded already
        import pyarrow as pa  # noqa: PLC0415 - loaded already

        dates = held.days[name].astype("datetime64[D]").astype(str)
        return table.append_column("bus", pa.array(np.full(len(dates), held.bus, object), pa.string())).append_column(
            "date", pa.array(dates, pa.string()))

    def tables(self) -> dict[str, pa.Table]:
        """Every table by name (:meth:`table`)."""
        return {name: self.table(name) for name in TABLES}

    def to_pandas(self, name: str) -> Any:
        """A table as a pandas DataFrame (with pandas installed)."""
        _needs("pandas")
        return self.table(name).to_pandas()

    def to_polars(self, name: str) -> Any:
        """A table as a Polars DataFrame (with polars installed)."""
        polars = _needs("polars")
        return polars.from_arrow(self.table(name))

    def _held(self) -> ArrowTables:
        if self._tables is None:
            self._decode()
        assert self._tables is not None
        return self._tables

    def statistics(self) -> Statistics:
        """What ``stats`` counts (``to_dict()``: its JSON document's counts)."""
        if self._statistics is None:
            self._decode()
        assert self._statistics is not None
        return self._statistics

    def findings(self) -> list[Finding]:
        """What is wrong on the bus, most severe first, as ``stats`` finds it."""
        self.statistics()
        return self._findings

    def frames(self) -> Iterator[Message]:
        """Every frame the decoding keeps, in order, as :class:`~decoders.message.Message`
        objects (role, pairing, flags, summary, params); decoded again, every frame held until
        the end (a capture of millions of frames is better read as :meth:`table`)."""
        collector = _Messages()
        self.decode([collector])
        return iter(collector.found)

    def transactions(self) -> Iterator[Transaction]:
        """Every request and what became of it, in order: the rows of the ``transactions``
        table as records."""
        for row in self.table("transactions").to_pylist():
            yield Transaction(**row)

    def _decode(self) -> None:
        from sniffer.exports.outputs import ParquetSink  # noqa: PLC0415 - pyarrow, when a table is asked for
        from sniffer.views.stats_view import Diagnosis  # noqa: PLC0415 - a view's imports, for the library alone

        tables, diagnosis = ParquetSink(None, self._args, self.analysis), Diagnosis()
        try:
            self._statistics = self.decode([tables, diagnosis])
        finally:
            tables.close()
        assert tables.tables is not None  # closed: a table for each name
        self._tables, self._findings = tables.tables, diagnosis.findings

    def __repr__(self) -> str:
        return f"<Capture {self.source!r} line {self.line.format()} timing {self.info.timing.value}>"

    def _repr_html_(self) -> str:
        """A notebook's summary: the capture, its line, and what ``stats`` counts of it."""
        statistics = self.statistics()
        rows = [("capture", self.source), ("line", self.line.format()), ("timing", self.info.timing.value),
                ("frames", f"{statistics.frames:,}"), ("duration", f"{statistics.duration_ns / 1e9:.3f} s"),
                ("slaves", ", ".join(str(slave) for slave in sorted({slave for slave, _ in statistics.per_function})))]
        rows += [(f"finding ({finding.severity})", finding.sentence) for finding in self.findings()]
        cells = "".join(f"<tr><th style='text-align:left'>{html.escape(key)}</th><td style='text-align:left'>"
                        f"{html.escape(str(value))}</td></tr>" for key, value in rows)
        tables = ", ".join(f"<code>{name}</code>" for name in TABLES)
        return f"<table>{cells}</table><p>tables: {tables} (<code>capture.table(NAME)</code>)</p>"


def _needs(module: str) -> Any:
    """``module``, or an error saying how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise RtuSniffError(ErrorKind.RUNTIME, f"{module} is not installed: pip install {module}") from None


class _Messages(Sink):
    """Every message kept, as objects."""

    wants_messages = True

    def __init__(self) -> None:
        self.found: list[Message] = []

    def messages(self, batch: AnnotatedBatch) -> None:
        self.found += list(batch)
