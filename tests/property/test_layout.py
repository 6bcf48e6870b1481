"""Properties of the table layout: whatever the cells and the width, nothing is cut and
nothing runs past the edge; a pipe gets one line per row with a field per column."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from sniffer.views.layout import ALWAYS, Cells, Column, Layout

FIXED = [Column("index", "#", right=True), Column("time", "time"), Column("role", "role"),
         Column("len", "len", right=True, keep=10), Column("lat", "lat ms", right=True, keep=20)]
FLEXIBLE = [Column("flags", "flags", flexible=True, min_width=7, max_width=18),
            Column("summary", "summary", flexible=True, min_width=20),
            Column("hex", "hex", flexible=True, keep=5, min_width=23, max_width=47)]
token = st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789.#=", min_size=1, max_size=12)
words = st.lists(token, max_size=12).map(" ".join)


@st.composite
def blocks(draw: st.DrawFn) -> tuple[dict[str, Cells], int]:
    rows = draw(st.integers(1, 6))
    cells = {c.key: Cells(draw(st.lists(token, min_size=rows, max_size=rows))) for c in FIXED}
    cells.update({c.key: Cells(draw(st.lists(words, min_size=rows, max_size=rows))) for c in FLEXIBLE})
    return cells, rows


@settings(max_examples=300, deadline=None)
@given(blocks(), st.integers(30, 260))
def test_terminal_lines_fit_and_keep_every_cell_whole(block: tuple[dict[str, Cells], int], width: int) -> None:
    cells, rows = block
    layout = Layout(FIXED + FLEXIBLE, width)
    text = layout.lines(cells, rows)
    lines = text.splitlines()
    fixed = sum(w for c, w in layout.shown() if not c.flexible) + len(layout.shown()) - 1
    if fixed + 7 <= width:  # the columns that always stay fit: nothing runs past the edge
        assert all(len(line) <= width for line in lines)
    # A summary column is never starved: it has its minimum, or goes below the row.
    for column, share in layout.shown():
        if column.flexible and not column.max_width:
            assert share >= column.min_width
    shown = {column.key for column, _ in layout.shown()} | {column.key for column, _ in layout.below}
    assert {c.key for c in FIXED + FLEXIBLE if c.keep == ALWAYS} <= shown
    # Fixed cells whole on their row's first line; flexible cells' words all there, in order.
    words_out = text.split()
    for column in FIXED:
        if column.key in shown:
            for value in cells[column.key].texts:
                assert value in text
    for column in FLEXIBLE:
        if column.key in shown:
            for value in cells[column.key].texts:
                for word in value.split():
                    assert word in words_out or any(word.startswith(piece) for piece in words_out)


@settings(max_examples=200, deadline=None)
@given(blocks())
def test_plain_lines_have_one_field_per_column(block: tuple[dict[str, Cells], int]) -> None:
    cells, rows = block
    columns = FIXED + FLEXIBLE[:1] + FLEXIBLE[2:] + FLEXIBLE[1:2]  # the summary last, as analyze lays them
    for column in columns[:-1]:  # one field each: the table writes flags and hex without spaces
        cells[column.key] = Cells([t.replace(" ", ",") or "-" for t in cells[column.key].texts])
    lines = Layout(columns, None).lines(cells, rows).splitlines()
    assert len(lines) == rows
    for row, line in enumerate(lines):
        fields = line.split(None, len(columns) - 1)
        assert fields[: len(columns) - 1] == [cells[c.key].texts[row] for c in columns[:-1]]
