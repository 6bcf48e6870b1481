"""Lines of text laid out by numpy, a field at a time for all lines at once.

A field is a matrix of bytes, one row per line, its columns the field's width; a NUL byte in
it stands for nothing. So a field holds texts of different lengths (numbers of fewer digits
than the widest, texts from a table), and a field that some lines lack (the ``..3202`` of a
span of one register) is NUL in their rows. :func:`lines` lays the fields side by side with a
newline after each row, drops the NULs by one ``bytes.replace`` and cuts the lines apart by one
``split``.

Why: the ``%`` of a template repeated for every line (:func:`~decoders.modbus.columnar_text.formatted`)
makes a Python object of every number and every field before it formats them; here a number's
digits are a few numpy operations over the whole column, which takes about half as long.

Every field here is ASCII but the ellipsis of :func:`bits`; none holds a newline or a NUL.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

Field = npt.NDArray[np.uint8]
UPPER_HEX = np.frombuffer(b"0123456789ABCDEF", np.uint8)
_ELLIPSIS = "…"


def decimal(values: npt.NDArray[np.integer]) -> Field:
    """Each value (none negative) in decimal digits, as ``%d`` writes it."""
    count = len(values)
    if count and int(values.min()) < 0:
        raise ValueError("decimal: negative values are not laid out")
    widest = int(values.max()) if count else 0
    width = len(str(widest))
    field = np.empty((count, width), np.uint8)
    rest = values.astype(np.int64)
    for place in range(width - 1, -1, -1):  # the last digit first
        quotient = rest // 10
        digit = (rest - quotient * 10).astype(np.uint8) + ord("0")
        # Leading zeros are nothing; a zero is written "0" (its last place).
        field[:, place] = digit if place == width - 1 else np.where(values >= 10 ** (width - 1 - place), digit, 0)
        rest = quotient
    return field


def upper_hex(values: npt.NDArray[np.integer], digits: int) -> Field:
    """Each value as ``digits`` upper-case hex digits, as ``%04X`` writes it (``digits=4``) for
    values below ``16 ** digits``."""
    shifts = 4 * np.arange(digits - 1, -1, -1)
    field: Field = UPPER_HEX[(values.astype(np.int64)[:, None] >> shifts) & 0x0F]
    return field


def chosen(index: npt.NDArray[np.integer], texts: Sequence[str]) -> Field:
    """``texts[index[i]]`` in each row (texts without NUL or newline)."""
    encoded = [text.encode() for text in texts]
    table = np.zeros((len(encoded), max(map(len, encoded), default=0)), np.uint8)
    for row, text in enumerate(encoded):
        table[row, : len(text)] = np.frombuffer(text, np.uint8)
    field: Field = table[index]
    return field


def present(where: npt.NDArray[np.bool_], field: Field | str) -> Field:
    """``field`` (or a text, the same in every row) in the rows ``where`` is true, nothing in the others."""
    if isinstance(field, str):
        field = np.broadcast_to(np.frombuffer(field.encode(), np.uint8), (len(where), len(field.encode())))
    hidden = np.flatnonzero(~where)
    # Rows copied, then those of the fewer kind set: a span's "..", shown in most rows, faster
    # than ``np.where`` over every row.
    if 2 * len(hidden) <= len(where):
        shown: Field = np.array(field, np.uint8)  # a copy (of a text's every row too)
        shown[hidden] = 0
        return shown
    shown = np.zeros(field.shape, np.uint8)
    rows = np.flatnonzero(where)
    shown[rows] = field[rows]
    return shown


def bits(data: bytes, starts: npt.NDArray[np.int64], counts: npt.NDArray[np.int64], shown: int) -> Field:
    """The first ``counts[i]`` bits from byte ``starts[i]`` of ``data``, least significant first,
    as ``0`` and ``1``: at most ``shown`` of them, then "…" (``_bit_string`` of
    :mod:`decoders.modbus.pdu`). Bytes past a count are read (up to the data's end) but not shown."""
    width = min(int(counts.max()), shown) if len(counts) else 0
    raw = np.frombuffer(data, np.uint8)
    at = np.minimum(starts[:, None] + np.arange((width + 7) // 8), max(len(raw) - 1, 0))
    more = counts > shown
    ellipsis = np.frombuffer(_ELLIPSIS.encode(), np.uint8) if more.any() else np.zeros(0, np.uint8)
    field: Field = np.empty((len(counts), width + len(ellipsis)), np.uint8)
    digits = field[:, :width]
    digits[:] = np.unpackbits(raw[at], axis=1, bitorder="little")[:, :width]
    digits += np.uint8(ord("0"))
    # Only the rows of fewer bits than the widest lose places (not a pass over every row: 40 %
    # less time for 16 000 answers of 1 to 8 bytes), and only those of more than shown get "…".
    short = np.flatnonzero(counts < width)
    digits[short] *= np.arange(width) < counts[short, None]
    if len(ellipsis):
        field[:, width:] = np.where(more[:, None], ellipsis, np.uint8(0))
    return field


def hex_words(data: bytes, starts: npt.NDArray[np.int64], counts: npt.NDArray[np.int64]) -> Field:
    """The ``counts[i]`` big-endian words from byte ``starts[i]`` of ``data`` as ``hex(" ", 2)``
    writes them, upper case: four digits a word, a space between words."""
    most = int(counts.max()) if len(counts) else 0
    raw = np.frombuffer(data, np.uint8)
    values = raw[np.minimum(starts[:, None] + np.arange(2 * most), max(len(raw) - 1, 0))]
    field = np.full((len(counts), max(5 * most - 1, 0)), ord(" "), np.uint8)
    digits = 2 * np.arange(2 * most) + np.arange(2 * most) // 2  # a byte's first digit: 4 digits and a space a word
    field[:, digits] = UPPER_HEX[values >> 4]
    field[:, digits + 1] = UPPER_HEX[values & 0x0F]
    if not len(counts) or int(counts.min()) == most:  # every row as wide (a polled bus's answers)
        return field
    # A word past a row's count is nothing, and so is the space before it.
    ends = np.maximum(5 * counts - 1, 0)
    shown: Field = np.where(np.arange(field.shape[1]) < ends[:, None], field, np.uint8(0))
    return shown


def lines(fields: Sequence[Field | str], count: int) -> list[str]:
    """The ``count`` lines of ``fields`` side by side (a text: the same in every line)."""
    if not count:
        return []
    laid = _laid(fields, count).tobytes()
    spelt = (laid.replace(b"\0", b"") if b"\0" in laid else laid).decode("utf-8").split("\n")
    spelt.pop()  # after the last line
    return spelt


def _laid(fields: Sequence[Field | str], count: int) -> Field:
    """The fields side by side, a row per line, a newline after each."""
    parts = [np.frombuffer(field.encode(), np.uint8)[None, :] if isinstance(field, str) else field for field in fields]
    parts.append(np.frombuffer(b"\n", np.uint8)[None, :])
    laid: Field = np.empty((count, sum(part.shape[1] for part in parts)), np.uint8)
    column = 0
    for part in parts:
        laid[:, column : column + part.shape[1]] = part
        column += part.shape[1]
    return laid
