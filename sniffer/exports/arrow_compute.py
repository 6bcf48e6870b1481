"""Arrow's compute functions called by name, without importing ``pyarrow.compute``.

``pyarrow.compute`` makes a Python function of every one of Arrow's compute functions as it is
imported, a noticeable part of the start of ``export --parquet``, which needs two of them
(``take``, and ``binary_join_element_wise`` where profiles name frames). ``call_function``, which
those Python functions call, lives in ``pyarrow._compute``, imported in a fraction of that; it is imported from
the documented ``pyarrow.compute`` only where a pyarrow moved it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa

try:
    from pyarrow._compute import call_function
except ImportError:  # a pyarrow that moved it: the documented name
    from pyarrow.compute import call_function


def arrow_call(name: str, *arguments: Any) -> pa.Array:
    """Arrow's compute function ``name`` of ``arguments`` (arrays and scalars)."""
    result: pa.Array = call_function(name, list(arguments))
    return result


def taken(column: pa.Array, rows: npt.NDArray[np.int64] | pa.Array) -> pa.Array:
    """The rows of ``column`` at ``rows`` (any of them, any number of times)."""
    return arrow_call("take", column, rows if isinstance(rows, pa.Array) else pa.array(rows, pa.int64()))
