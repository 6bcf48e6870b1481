"""Floats spelt as ``repr`` (and so ``json.dumps``) spells them, a column at a time.

``repr`` of a list of floats finds each number's shortest digits that read back to the same
float, one number at a time, and the JSON records spell three per frame (``t``, ``t_end``,
``latency_s``). Arrow's cast of a float64 array to strings finds the same shortest digits in C,
a column at once, but spells some numbers differently: an integral value without ``.0`` (``2``
for ``2.0``), and an exponent, or none, at other magnitudes than ``repr``
(``1.2345e+10``; ``0.000012345``). So Arrow's text is kept where it is what ``repr``
writes -- fixed point with a fraction, at a magnitude from 1e-4 to 1e16, where ``repr``
writes fixed point too; an integral value in that range gets its ``.0``; every other number
(zero, an exponent either way, NaN) is spelt by ``repr``. Columns shorter than
``ARROW_FROM`` go to ``repr`` whole: Arrow's fixed cost per call, and its import on first
use, would not pay.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from sniffer.encoding.rows import Pieces, number_texts

#: Columns from this many numbers are spelt through Arrow.
ARROW_FROM = 512
#: Magnitudes ``repr`` spells in fixed point: [1e-4, 1e16).
FIXED_LOW, FIXED_HIGH = 1e-4, 1e16


def float_texts(column: npt.NDArray[np.float64]) -> Pieces:
    """Each float as ``repr`` spells it (see the module docstring)."""
    count = len(column)
    if count < ARROW_FROM:
        return number_texts(column)
    text, sizes = _arrow_texts(column)
    pieces = Pieces(text.split(b","), sizes)
    magnitude = np.abs(column)
    fixed = (magnitude >= FIXED_LOW) & (magnitude < FIXED_HIGH)
    if text.count(b"e") or text.count(b".") != count:  # some spelt otherwise: find which
        has_dot, has_exponent = _rows_holding(text, count, b"."), _rows_holding(text, count, b"e")
        fixed &= ~has_exponent
        for row in np.flatnonzero(fixed & ~has_dot).tolist():
            pieces[row] += b".0"
            sizes[row] += 2
    for row in np.flatnonzero(~fixed).tolist():
        pieces[row] = repr(float(column[row])).encode()
        sizes[row] = len(pieces[row])
    return pieces


def _arrow_texts(column: npt.NDArray[np.float64]) -> tuple[bytes, npt.NDArray[np.int64]]:
    """Arrow's spelling of every number, joined by commas; the size of each."""
    import pyarrow as pa  # noqa: PLC0415 - imported only for long columns (see the module docstring)
    import pyarrow.compute as pc  # noqa: PLC0415

    texts = pc.cast(pa.array(column, pa.float64()), pa.string())
    offsets = np.frombuffer(texts.buffers()[1], np.int32, len(column) + 1)
    as_list = pa.ListArray.from_arrays(pa.array([0, len(column)], pa.int32()), texts)
    joined: bytes = pc.binary_join(as_list, ",")[0].as_buffer().to_pybytes()
    return joined, np.diff(offsets).astype(np.int64)


def _rows_holding(text: bytes, count: int, character: bytes) -> npt.NDArray[np.bool_]:
    """Which of the ``count`` comma-separated pieces of ``text`` hold ``character``."""
    characters = np.frombuffer(text, np.uint8)
    row_of = np.zeros(len(characters), np.int64)
    row_of[np.flatnonzero(characters == ord(",")) + 1] = 1
    np.cumsum(row_of, out=row_of)
    holding = np.zeros(count, np.bool_)
    holding[row_of[characters == ord(character)]] = True
    return holding
