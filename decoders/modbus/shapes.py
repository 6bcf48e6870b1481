"""Per-frame facts the matcher needs, computed for a whole batch with numpy.

For every frame: address, function code, whether its length fits a request or a
response of that code (from the same :data:`LAYOUTS` rule tables the framer's fast
path uses), and the *keys* that decide whether a response answers a request: a
request's key is what its answer must show (the byte count for the registers or
coils asked, the echoed address and value or count, the sub-function, the MEI
type), a response's key is what it shows. A response answers a request when their
function codes and keys are equal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameBatch
from decoders.framing.rule_tables import OWN_RULE, REQUEST_RULES, RESPONSE_RULES, padded_bytes
from decoders.modbus.codecs import fits_request, fits_response
from decoders.modbus.codes import DIAGNOSTICS, EXCEPTION_BIT
from decoders.modbus.layouts import EXCEPTION_LENGTH, MEI_EXCEPTION_LENGTH

FITS_REQUEST = 1
FITS_RESPONSE = 2
IS_EXCEPTION = 4
MIN_ADU = 4


@dataclass(frozen=True, slots=True)
class Shapes:
    """Columns of per-frame facts."""

    slave: npt.NDArray[np.int64]
    function: npt.NDArray[np.int64]
    shape: npt.NDArray[np.int64]
    request_key: npt.NDArray[np.int64]
    response_key: npt.NDArray[np.int64]


def frame_shapes(frames: FrameBatch) -> Shapes:
    starts, ends = frames.offsets[:-1], frames.offsets[1:]
    lengths = ends - starts
    padded = padded_bytes(frames.data)
    # Byte k of each frame from the bytes k on (no index array made per byte: a third less time).
    raw = padded[1:].take(starts).astype(np.intp)
    b2, b3, b4, b5 = (padded[k:].take(starts).astype(np.int64) for k in (2, 3, 4, 5))
    long_enough = lengths >= MIN_ADU
    exception = (raw & EXCEPTION_BIT) != 0
    fits_req = long_enough & ~exception & REQUEST_RULES.fits(padded, starts, raw, lengths)
    fits_resp = long_enough & ~exception & RESPONSE_RULES.fits(padded, starts, raw, lengths)
    exception_fit = long_enough & exception & (
        (lengths == EXCEPTION_LENGTH) | ((raw == (43 | EXCEPTION_BIT)) & (lengths == MEI_EXCEPTION_LENGTH))
    )
    # FC 8 sub-function 0 (return query data) echoes any number of bytes, both ways.
    echo = long_enough & (raw == DIAGNOSTICS) & (b2 == 0) & (b3 == 0) & (lengths >= 6)
    shape = (fits_req | echo) * FITS_REQUEST | (fits_resp | echo) * FITS_RESPONSE
    shape |= exception_fit * (FITS_RESPONSE | IS_EXCEPTION)
    shape = shape.astype(np.int64)
    _special_shapes(frames, shape, np.flatnonzero(OWN_RULE[raw] & long_enough))
    return Shapes(
        slave=padded.take(starts).astype(np.int64),
        function=raw.astype(np.int64),
        shape=shape,
        request_key=_request_keys(raw, b2, b3, b4, b5),
        response_key=_response_keys(raw, b2, b3, b4, b5),
    )


def _special_shapes(frames: FrameBatch, shape: npt.NDArray[np.int64], positions: npt.NDArray[np.intp]) -> None:
    for position in positions.tolist():
        adu = frames.data[int(frames.offsets[position]) : int(frames.offsets[position + 1])]
        exception = bool(adu[1] & EXCEPTION_BIT)
        value = FITS_REQUEST if not exception and fits_request(adu) else 0
        if fits_response(adu):
            value |= FITS_RESPONSE | (IS_EXCEPTION if exception else 0)
        shape[position] = value


Column = npt.NDArray[np.int64]


#: Bytes 2 to 5 of each frame: what keys are made of.
Head = tuple[Column, Column, Column, Column]
KeyOf = Callable[[Column, Column, Column, Column], Column]


def _count(b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return b4 << 8 | b5


def _echo(b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return (b2 << 24) | (b3 << 16) | (b4 << 8) | b5


def _sub_function(b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return b2 << 8 | b3


def _byte_2(b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return b2


#: What a request's key is made of, per group of function codes: the byte count that answers
#: the coils (FC 1, 2) or registers (FC 3, 4, 23) asked, the echoed address and value or count
#: (FC 5, 6, 15, 16, 22), the sub-function (FC 8), the MEI type (FC 43).
_REQUEST_KEYS: tuple[tuple[tuple[int, ...], KeyOf], ...] = (
    ((1, 2), lambda *head: (_count(*head) + 7) // 8),
    ((3, 4, 23), lambda *head: 2 * _count(*head)),
    ((5, 6, 15, 16, 22), _echo),
    ((8,), _sub_function),
    ((43,), _byte_2),
)
#: What a response's key is: its byte count, the echo, the sub-function, the MEI type.
_RESPONSE_KEYS: tuple[tuple[tuple[int, ...], KeyOf], ...] = (
    ((1, 2, 3, 4, 23), _byte_2),
    ((5, 6, 15, 16, 22), _echo),
    ((8,), _sub_function),
    ((43,), _byte_2),
)


def _kinds(groups: tuple[tuple[tuple[int, ...], KeyOf], ...]) -> npt.NDArray[np.intp]:
    """Per function code: 1 + the index of its group in ``groups``, 0 for the others (a
    table: ``np.isin`` sorts per call)."""
    kinds = np.zeros(256, np.intp)
    for kind, (functions, _) in enumerate(groups, start=1):
        kinds[list(functions)] = kind
    return kinds


_REQUEST_KEY_KINDS = _kinds(_REQUEST_KEYS)
_RESPONSE_KEY_KINDS = _kinds(_RESPONSE_KEYS)


def _keys(kinds: npt.NDArray[np.intp], groups: tuple[tuple[tuple[int, ...], KeyOf], ...], head: Head) -> Column:
    """The key of every frame by its group (``kinds``: 1 + the group's index, 0 for no key),
    made only for the groups present: a bus uses few, a polling one often one. Chosen by one
    gather, faster than ``np.choose``."""
    present = np.flatnonzero(np.bincount(kinds, minlength=len(groups) + 1))
    if len(present) == 1 and present[0] > 0:
        return groups[int(present[0]) - 1][1](*head)
    made = present[present > 0]
    # The keys of the groups present laid end to end (no key first), one gather from them.
    place = np.zeros(len(groups) + 1, np.intp)
    place[made] = np.arange(1, len(made) + 1)
    size = len(kinds)
    laid = np.concatenate([np.zeros(size, np.int64), *(groups[kind - 1][1](*head) for kind in made.tolist())])
    keys: Column = laid[place[kinds] * size + np.arange(size)]
    return keys


def _request_keys(raw: npt.NDArray[np.intp], b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return _keys(_REQUEST_KEY_KINDS[raw], _REQUEST_KEYS, (b2, b3, b4, b5))


def _response_keys(raw: npt.NDArray[np.intp], b2: Column, b3: Column, b4: Column, b5: Column) -> Column:
    return _keys(_RESPONSE_KEY_KINDS[raw], _RESPONSE_KEYS, (b2, b3, b4, b5))
