"""Columns laid out for a width: what every table of rtusniff (``analyze``, ``stats``, the live
view) prints through.

Two modes, one column model:

* **terminal** (:class:`Layout` with a width): the columns that fit, in the order given; when
  they do not all fit, the ones with the lowest ``keep`` go first (never one with ``keep`` of
  ``ALWAYS``). Fixed columns are as wide as their widest cell (never cut: a number longer than
  its column widens the column); the flexible columns share what is left, and their cells wrap
  at whole words onto continuation lines. Styles (ANSI, through rich's :class:`~rich.style.Style`)
  only when the console has colour.
* **plain** (width ``None``: a pipe, a file): one line per row, every column padded to the widest
  cell seen so far, no wrapping, no styles, an empty cell written ``-`` so that ``awk`` counts the
  same fields on every line; the last column is not padded.

Rows come in columns (one list of cell texts per column) so that a block of thousands of rows
costs one ``%`` format per line in plain mode.
"""

from __future__ import annotations

import argparse
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from rich.color import ColorSystem
    from rich.console import Console

#: ``keep`` of a column that is never dropped.
ALWAYS = 1_000
#: Indent of a summary written below its row, on a terminal too narrow to give it a column.
BELOW_INDENT = 4


def terminal_colors(console: Console) -> ColorSystem | None:
    """The colours to style with on ``console``: ``None`` off a terminal, with ``NO_COLOR``,
    or on a console that takes no ANSI codes."""
    from rich.color import ColorSystem  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

    if not console.is_terminal or console.color_system is None:
        return None
    # rich's names of the colour systems that take ANSI styles ("windows", the legacy console, takes none).
    ansi = {"standard": ColorSystem.STANDARD, "256": ColorSystem.EIGHT_BIT, "truecolor": ColorSystem.TRUECOLOR}
    return ansi.get(console.color_system)


def terminal_width(args: argparse.Namespace, console: Console) -> int | None:
    """The width to lay a table out for: ``--width`` (0: plain lines), else the terminal's,
    else ``None`` (plain lines for a pipe or a file)."""
    if args.width is not None:
        return int(args.width) or None
    return console.width if console.is_terminal else None


def terminal_layout(args: argparse.Namespace, out: TextIO) -> tuple[int | None, ColorSystem | None]:
    """The width to lay a table out for on ``out`` (:func:`terminal_width`) and, where there
    is one, the colours to style it with (:func:`terminal_colors`); rich is imported here, for
    the tables alone."""
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

    console = Console(file=out)
    width = terminal_width(args, console)
    return width, terminal_colors(console) if width else None


@dataclass(frozen=True)
class Column:
    """One column: its header, alignment, whether it takes the room left (and wraps), and how
    much it matters when the width runs out (higher stays longer)."""

    key: str
    header: str
    right: bool = False
    flexible: bool = False
    keep: int = ALWAYS
    #: A flexible column is shown only with at least this much room.
    min_width: int = 12
    #: A flexible column takes no more than this (0: no limit).
    max_width: int = 0


#: A column's cells; styles (rich style strings, "" for none) optional, one per cell.
@dataclass
class Cells:
    texts: list[str]
    styles: list[str] | None = None


@dataclass
class Layout:
    """Lays out blocks of rows; keeps the widths it has used so that blocks line up."""

    columns: Sequence[Column]
    #: Terminal width; ``None`` for plain output.
    width: int | None = None
    color_system: ColorSystem | None = None
    widths: dict[str, int] = field(default_factory=dict)
    _styles: dict[tuple[str, str], str] = field(default_factory=dict)
    #: Columns written below each row (a terminal too narrow for them), as the last layout found.
    below: list[tuple[Column, int]] = field(default_factory=list)

    @property
    def plain(self) -> bool:
        return self.width is None

    def gap(self) -> str:
        return "  " if self.width is None or self.width >= 120 else " "

    def _header_text(self, position: int, column: Column) -> str:
        """A plain table's heading line starts with ``#``, as its other comment lines do."""
        if self.plain and position == 0 and not column.header.startswith("#"):
            return "#" + column.header
        return column.header

    def shown(self) -> list[tuple[Column, int]]:
        """The columns shown and their widths, from the widths seen so far."""
        columns = [(c, max(len(self._header_text(p, c)), self.widths.get(c.key, 0)))
                   for p, c in enumerate(self.columns)]
        if self.width is None:
            return columns
        shown, self.below = _fit(columns, self.width, len(self.gap()))
        return shown

    def hidden(self) -> list[str]:
        """The headers of the columns this width has no room for."""
        shown = {column.key for column, _ in self.shown()} | {column.key for column, _ in self.below}
        return [column.header for column in self.columns if column.key not in shown and column.header]

    def header(self) -> str:
        """The header line(s)."""
        shown = self.shown()
        texts = [[self._header_text(p, column)] for p, (column, _) in enumerate(shown)]
        return self._join(shown, texts, [""] * len(shown), header=True)

    def measure(self, cells: dict[str, Cells]) -> None:
        """Widen the columns to what ``cells`` hold (a flexible one on a terminal then takes no
        more than that, up to its ``max_width``)."""
        for column in self.columns:
            # A flexible column without a cap takes what is left whatever its cells hold.
            if (column.flexible and not column.max_width) or column.key not in cells:
                continue
            texts = cells[column.key].texts
            if texts:
                widest = max(map(len, texts))
                if widest > self.widths.get(column.key, 0):
                    self.widths[column.key] = widest

    def lines(self, cells: dict[str, Cells], count: int, *, measured: bool = False) -> str:
        """``count`` rows as text, each ending in a newline (``measured``: :meth:`measure` has
        seen these cells already)."""
        if not measured:
            self.measure(cells)
        if self.plain:
            return self._plain_lines(cells, count)
        shown = self.shown()
        out = []
        for row in range(count):
            texts, styles = [], []
            for column, width in shown:
                column_cells = cells[column.key]
                text = column_cells.texts[row]
                texts.append(_wrap(text, width) if column.flexible else [text])
                styles.append(column_cells.styles[row] if column_cells.styles else "")
            out.append(self._join(shown, texts, styles))
            for column, width in self.below:
                text = cells[column.key].texts[row]
                out.extend(f"{' ' * BELOW_INDENT}{line}\n" for line in _wrap(text, width) if text)
        return "".join(out)

    def plain_prefixes(self, cells: dict[str, Cells], count: int) -> list[str]:
        """Plain rows of every column but the last, each with the gap after it: the last
        column's cell (the summary) is added by whoever knows it (:mod:`sniffer.views.table`)."""
        columns = self.shown()[:-1]
        gap = self.gap()
        pattern = "".join(f"%{'' if column.right else '-'}{width}s{gap}" for column, width in columns)
        lists = [texts if "" not in texts else [text or "-" for text in texts]
                 for texts in (cells[column.key].texts for column, _ in columns)]
        return [pattern % row for row in zip(*lists, strict=True)][:count]

    def _plain_lines(self, cells: dict[str, Cells], count: int) -> str:
        columns = self.shown()
        last = len(columns) - 1
        pattern = self.gap().join(
            ("%s" if place == last else f"%{'' if column.right else '-'}{width}s")
            for place, (column, width) in enumerate(columns)
        ) + "\n"
        lists = [texts if "" not in texts else [text or "-" for text in texts]
                 for texts in (cells[column.key].texts for column, _ in columns)]
        return "".join([pattern % row for row in zip(*lists, strict=True)][:count])

    def _join(self, shown: list[tuple[Column, int]], texts: list[list[str]], styles: list[str],
              header: bool = False) -> str:
        height = max(map(len, texts))
        gap = self.gap()
        lines = []
        for line in range(height):
            parts: list[str] = []
            for (column, width), cell_lines, style in zip(shown, texts, styles, strict=True):
                text = cell_lines[line] if line < len(cell_lines) else ""
                first_heading = header and self.plain and not parts
                padded = text.rjust(width) if column.right and not first_heading else text.ljust(width)
                parts.append(self.styled(padded, "bold" if header else style) if text else padded)
            lines.append(gap.join(parts).rstrip() + "\n")
        return "".join(lines)

    def styled(self, text: str, style: str) -> str:
        if not style or self.color_system is None:
            return text
        key = (style, text)
        styled = self._styles.get(key)
        if styled is None:
            from rich.style import Style  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

            styled = Style.parse(style).render(text, color_system=self.color_system)
            if len(self._styles) < 4096:
                self._styles[key] = styled
        return styled


#: Columns kept at least this much (a frame's request and latency) keep their place in the row: the
#: summary goes below it first.
BELOW_BEFORE = 20


def _fit(columns: list[tuple[Column, int]], width: int,
         gap: int) -> tuple[list[tuple[Column, int]], list[tuple[Column, int]]]:
    """Drop the least needed columns until the rest fit ``width``; share what is left among the
    flexible ones (each up to its ``max_width``, the last one the rest). Where even then the
    uncapped flexible columns (the summary) have less than their minimum, they go below the
    row, indented, as wide as the terminal allows: the second list."""
    kept = list(columns)
    natural = {c.key: w for c, w in columns}

    def room() -> int:
        fixed = sum(w for c, w in kept if not c.flexible)
        return width - fixed - gap * (len(kept) - 1)

    while True:
        flexible = [c for c, _ in kept if c.flexible]
        if room() >= sum(c.min_width for c in flexible):
            break
        droppable = [pair for pair in kept if pair[0].keep < ALWAYS]
        if not droppable:
            break
        least = min(droppable, key=lambda pair: pair[0].keep)
        uncapped = [c for c in flexible if not c.max_width]
        if least[0].keep >= BELOW_BEFORE and uncapped and room() >= sum(c.min_width for c in flexible if c.max_width):
            break  # the summary goes below the row rather than this column away
        kept.remove(least)
    below: list[tuple[Column, int]] = []
    if room() < sum(c.min_width for c, _ in kept if c.flexible):
        below = [(c, max(width - BELOW_INDENT, 1)) for c, _ in kept if c.flexible and not c.max_width]
        kept = [(c, w) for c, w in kept if (c, max(width - BELOW_INDENT, 1)) not in below]
    left = room()
    flexible = [c for c, _ in kept if c.flexible]
    shares: dict[str, int] = {}
    # Capped columns (hex) first, leaving the others their minimum; the uncapped share the rest.
    uncapped = [c for c in flexible if not c.max_width]
    for column in flexible:
        if column.max_width:
            reserve = sum(c.min_width for c in uncapped)
            # A quarter of the room at most while an uncapped column (the summary) wants it.
            share = min(column.max_width, natural[column.key], max(column.min_width, left // 4) if uncapped else left)
            shares[column.key] = max(min(share, left - reserve), 1)
            left -= shares[column.key]
    for position, column in enumerate(uncapped):
        shares[column.key] = max(left // (len(uncapped) - position), 1)
        left -= shares[column.key]
    return [(c, shares[c.key] if c.flexible else w) for c, w in kept], below


def _wrap(text: str, width: int) -> list[str]:
    """``text`` in lines of at most ``width``, broken between words (a word longer than the
    line is the only thing ever broken)."""
    if len(text) <= width:
        return [text]
    return textwrap.wrap(text, width, break_on_hyphens=False) or [""]


#: What keeps the words of one field of a note together while it is wrapped (no text holds it).
_JOINED = "\x00"


def note_lines(text: str, width: int) -> list[str]:
    """A note above or below a table (``source  line 19200 8E1  t3.5 2005 µs``) in lines of at
    most ``width``: fields are separated by two spaces, and a line breaks between fields, so a
    label stays with its value; a field wider than the line breaks between its words."""
    fields = text.split("  ")
    if len(text) <= width or len(fields) == 1:
        return _wrap(text, width)
    lines: list[str] = []
    for joined in textwrap.wrap("  ".join(f.replace(" ", _JOINED) for f in fields), width, break_on_hyphens=False,
                                break_long_words=False):
        line = joined.replace(_JOINED, " ")
        lines += _wrap(line, width)
    return lines
