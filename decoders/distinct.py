"""The distinct values of a column, ascending: what ``np.unique(values)`` returns.

numpy 2.3 and later find them by a hash table where ``np.unique`` is asked for nothing else,
which is several times slower than sorting for the columns here (keys of a batch, many or few
values), and its first call imports ``numpy.ma`` at a command's start. Small integers are
counted instead (a bincount, faster still); a few values are sorted.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

#: The widest span of integers counted rather than sorted.
COUNTED_SPAN = 1 << 16
#: Fewer values than this are sorted whatever they are (counting them costs more).
FEW = 256


def distinct(values: npt.ArrayLike) -> npt.NDArray[Any]:
    """The distinct values of ``values`` (one dimension), ascending, of its dtype."""
    values = np.asarray(values)
    if not len(values):
        return values[:0].copy()
    if values.dtype.kind in "iu" and len(values) >= FEW:
        low, high = int(values.min()), int(values.max())
        if high - low < COUNTED_SPAN:
            counts = np.bincount(np.subtract(values, low, dtype=np.int64) if low else values)
            found: npt.NDArray[Any] = np.flatnonzero(counts) + low
            return found.astype(values.dtype, copy=False)
    ordered = np.sort(values)
    new = np.empty(len(ordered), np.bool_)
    new[0] = True
    np.not_equal(ordered[1:], ordered[:-1], out=new[1:])
    kept: npt.NDArray[Any] = ordered[new]
    return kept
