"""The texts of what a batch's frames say, spelt from the one decoded form, all frames at once.

Every writer spells a message's decoded part here from :class:`~decoders.decoded_batch.DecodedColumns`
(a summary per frame, a long table of params, each frame's protocol and remarks; frames alike given
once), whichever way the annotator decoded it: its JSONL record's part from ``params`` to
``remarks``, its MCAP log text after the frame index and its ``/slave/N/params`` members. Every
piece of every frame is laid out in one numpy object array (the params no profile names from the
tables of :mod:`sniffer.encoding.param_text`, a named param from its own JSON and member, made
once per param) with its size beside it, and each frame's pieces are joined by one ``join``.

The texts are exactly those of ``tests/oracles.py``: the tests hold them to it
(``tests/property/test_decoded_texts.py``). A ``join`` per frame: one ``join`` of a whole batch's
pieces, cut into views, was slower on registers and on coils alike.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt
import orjson

from decoders.decoded_batch import AnnotatedBatch, ColumnarParams, DecodedColumns
from decoders.distinct import distinct
from decoders.frame import PROTOCOL_NAMES
from decoders.message import ROLE_NAMES
from decoders.runs import spread
from sniffer.encoding.param_text import (
    NO_VALUE_END,
    PARAM_JSON,
    PARAM_MEMBERS,
    WORDS,
    encode_json,
    param_start,
    param_tables,
)
from sniffer.encoding.rows import Pieces

#: Params spelt at once (see :func:`_in_slices`).
SLICE_PARAMS = 1 << 16
#: The tables as numpy object arrays (indexed by a column in C), built at first use.
_tables: dict[str, npt.NDArray[Any]] = {}
#: The end of a record of a Modbus frame without remarks (every frame in columns).
_PLAIN_END = b',"protocol":"modbus","remarks":[]'
_PROTOCOL_JSON = {code: f'"{name}"'.encode() for code, name in PROTOCOL_NAMES.items()}
Text = TypeVar("Text", str, bytes)


class FrameTexts:
    """The texts of the frames of ``decoded``, spelt once per frame given (one per group of frames
    alike); every list in the order of :attr:`positions`."""

    def __init__(self, decoded: DecodedColumns) -> None:
        self.decoded = decoded
        self.positions = decoded.positions
        self.spelt_positions = decoded.spelt_positions
        self.each = decoded.each

    def record_tails(self) -> Pieces:
        """Each frame's JSONL record part from ``params`` to the end of ``remarks``."""
        return self._each_piece(self.spelt_record_tails())

    def spelt_record_tails(self) -> Pieces:
        """:meth:`record_tails` of the frames given (one per group of frames alike)."""
        summaries = list(map(orjson.dumps, self.decoded.spelt_summaries()))
        named, ends = self._named_texts(members=False), self._ends()
        return _in_slices(self.decoded.params(), lambda params, frames: _record_tails(
            params, summaries[frames], named, None if ends is None else ends[frames]))

    def log_heads(self, roles: npt.NDArray[np.integer[Any]]) -> list[bytes]:
        """Each frame's log text after its index: `` response: HR = …`` (``roles``: the batch's)."""
        return self.each([f" {ROLE_NAMES[role]}: {summary}".encode()
                          for role, summary in zip(roles[self.spelt_positions].tolist(),
                                                   self.decoded.spelt_summaries(), strict=True)])

    def numeric_members(self) -> Pieces:
        """Each frame's values as the members of a JSON object by code (or address), its closing
        brace included, or ``b""``: it carried none (a state word: its raw value; a marker: none)."""
        named = self._named_texts(members=True)
        return self._each_piece(_in_slices(self.decoded.params(), lambda params, _: _numeric_members(params, named)))

    def _each_piece(self, spelt: Pieces) -> Pieces:
        inverse = self.decoded.inverse
        return spelt if inverse is None else spelt.take(inverse)

    def _named_texts(self, *, members: bool) -> npt.NDArray[Any] | None:
        """The JSON (or with ``members``, the params member) of each named param, ``None`` where none is."""
        params = self.decoded.named()
        if params is None:
            return None
        if members:
            return _objects(PARAM_MEMBERS.made(params))
        return _objects([b"," + text for text in PARAM_JSON.made(params)])

    def _ends(self) -> list[bytes] | None:
        """Each frame given's record end from ``,"protocol"`` on (``None``: :data:`_PLAIN_END` for all)."""
        given = self.decoded.protocols_and_remarks()
        if given is None:
            return None
        return [b"".join((b',"protocol":', _PROTOCOL_JSON[protocol], b',"remarks":',
                          encode_json(list(remarks)) if remarks else b"[]")) for protocol, remarks in given]


def each_message(batch: AnnotatedBatch, spell: Callable[[FrameTexts], list[Text]]) -> list[Text]:
    """``spell``'s texts of every kept message of ``batch``, in order."""
    return batch.each_message(lambda decoded: spell(FrameTexts(decoded)))


def _in_slices(params: ColumnarParams, spell: Callable[[ColumnarParams, slice], Pieces]) -> Pieces:
    """``spell`` over the frames of ``params`` a slice of about :data:`SLICE_PARAMS` params at a
    time (the frames' slice given too), put end to end: a batch of coil answers has hundreds of
    thousands of params, and the columns laid out for them at once would take tens of MB."""
    ends = np.cumsum(params.sizes)
    total = int(ends[-1]) if len(ends) else 0
    if total <= SLICE_PARAMS:
        return spell(params, slice(None))
    cuts = distinct(np.searchsorted(ends, np.arange(SLICE_PARAMS, total, SLICE_PARAMS), side="right")).tolist()
    texts: list[bytes] = []
    sizes: list[npt.NDArray[np.int64]] = []
    for first, last in zip([0, *cuts], [*cuts, len(ends)], strict=True):
        if first == last:
            continue
        start, stop = int(ends[first] - params.sizes[first]), int(ends[last - 1])
        sliced = ColumnarParams(params.sizes[first:last], params.address[start:stop], params.value[start:stop],
                                None if params.name is None else params.name[start:stop])
        spelt = spell(sliced, slice(first, last))
        texts += spelt
        sizes.append(spelt.sizes)
    return Pieces(texts, np.concatenate(sizes))


def _record_tails(params: ColumnarParams, summaries: list[bytes], named: npt.NDArray[Any] | None,
                  frame_ends: list[bytes] | None) -> Pieces:
    """:meth:`FrameTexts.record_tails` of the frames of ``params`` (their summaries in JSON;
    ``named``: the JSON of each named value, after a comma; ``frame_ends``: each frame's from
    ``,"protocol"`` on, ``None``: :data:`_PLAIN_END`)."""
    sizes, address, value, name = params
    # A frame's pieces: '"params":[', a start and an end per param, '],"summary":', its summary, the end.
    layout = _Layout(2 * sizes + 4)
    base = layout.base
    layout.put(base, b'"params":[')
    at = spread(base + 1, sizes, 2)
    starts, start_sizes = _by_address("starts", address)
    words = np.maximum(value, 0)
    ends, end_sizes = _table("value_ends")[words], _sizes("value_ends")[words]
    unvalued = np.flatnonzero(value < 0)
    ends[unvalued], end_sizes[unvalued] = NO_VALUE_END, len(NO_VALUE_END)
    if named is not None and name is not None:  # a named param is its JSON, whole, at its start
        rows = np.flatnonzero(name >= 0)
        starts[rows] = named[name[rows]]
        start_sizes[rows] = _lengths(starts[rows])
        ends[rows], end_sizes[rows] = b"", 0
    layout.put(at, starts, start_sizes)
    layout.put(at + 1, ends, end_sizes)
    after = base + 2 * sizes
    layout.put(after + 1, b'],"summary":')
    layout.put(after + 2, _objects(summaries), np.fromiter(map(len, summaries), np.int64, len(summaries)))
    if frame_ends is None:
        layout.put(after + 3, _PLAIN_END)
    else:
        layout.put(after + 3, _objects(frame_ends), np.fromiter(map(len, frame_ends), np.int64, len(frame_ends)))
    layout.without_comma(base[sizes > 0] + 1)
    return layout.texts()


def _numeric_members(params: ColumnarParams, named: npt.NDArray[Any] | None) -> Pieces:
    """:meth:`FrameTexts.numeric_members` of the frames of ``params`` (``named``: each named
    value's member after a comma, or ``b""``: no reading, which a named frame may carry alone)."""
    sizes, address, value, name = params
    frame = np.repeat(np.arange(len(sizes)), sizes)
    valued = value >= 0  # an FC 23 request's read params carry none, its written ones do
    carried = np.zeros(len(sizes), np.bool_)
    carried[frame[valued]] = True
    named_frames = np.zeros(len(sizes), np.bool_)
    members = member_sizes = None
    if named is not None and name is not None:
        each = np.append(named, b"")  # -1 (unnamed): the last
        members, member_sizes = each[name], _lengths(each)[name]
        named_frames[frame[name >= 0]] = True
        carried[named_frames] = False
        carried[frame[member_sizes > 0]] = True  # a named frame: where it carries a reading
    # A named frame's every param is laid out (one without a reading is an empty member).
    kept = np.flatnonzero(carried[frame] & (valued | named_frames[frame]))
    counts = np.bincount(frame[kept], minlength=len(sizes))
    # A frame's pieces: a key and a value per param, then '}' (nothing, when it carried none).
    layout = _Layout(2 * counts + 1)
    at = spread(layout.base, counts, 2)
    keys, key_sizes = _by_address("keys", address[kept])
    words = np.maximum(value[kept], 0)  # a register's word or a coil's 0 or 1: looked up, not formatted
    numbers, number_sizes = _table("numbers")[words], _sizes("numbers")[words]
    firsts = layout.base[carried & ~named_frames]
    if members is not None and member_sizes is not None:  # a named param's member is whole at its key
        rows = np.flatnonzero(named_frames[frame[kept]])
        keys[rows], key_sizes[rows] = members[kept[rows]], member_sizes[kept[rows]]
        numbers[rows], number_sizes[rows] = b"", 0
        shown = rows[key_sizes[rows] > 0]
        _, first = np.unique(frame[kept[shown]], return_index=True)  # each frame's first member
        firsts = np.concatenate([firsts, at[shown[first]]])
    layout.put(at, keys, key_sizes)
    layout.put(at + 1, numbers, number_sizes)
    layout.put((layout.base + 2 * counts)[carried], b"}")
    layout.put(layout.base[~carried], b"")
    layout.without_comma(firsts)
    return layout.texts()


def _lengths(pieces: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    return np.fromiter(map(len, pieces.tolist()), np.int64, len(pieces))


class _Layout:
    """Texts of pieces (``widths``: how many pieces each, at least one), laid out in one object
    array with each piece's size beside it; each text joined alone."""

    def __init__(self, widths: npt.NDArray[np.int64]) -> None:
        ends = np.cumsum(widths)
        #: Where each text's pieces begin.
        self.base = ends - widths
        self._last = ends - 1
        self._pieces = np.empty(int(ends[-1]) if len(ends) else 0, object)  # every piece is put
        self._sizes = np.zeros(len(self._pieces), np.int64)

    def put(self, places: npt.NDArray[np.int64], pieces: npt.NDArray[Any] | bytes,
            sizes: npt.NDArray[np.int64] | None = None) -> None:
        """``pieces`` (one for all, or one each) at ``places``; ``sizes``: theirs, where not one piece."""
        self._pieces[places] = pieces
        if isinstance(pieces, bytes):
            self._sizes[places] = len(pieces)
        else:
            assert sizes is not None
            self._sizes[places] = sizes

    def without_comma(self, places: npt.NDArray[np.int64]) -> None:
        """The pieces at ``places`` (a first member, whose table entry begins with a comma) without it."""
        self._pieces[places] = _objects([piece[1:] for piece in self._pieces[places].tolist()])
        self._sizes[places] -= 1

    def texts(self) -> Pieces:
        """Each text, joined alone: a join of a whole batch's pieces reads each piece twice (to
        size, then to copy) from far beyond the cache (a coil answer's are kilobytes)."""
        pieces, join = self._pieces.tolist(), b"".join
        ends = self._last + 1
        texts = [join(pieces[start:end]) for start, end in zip(self.base.tolist(), ends.tolist(), strict=True)]
        sizes = np.cumsum(self._sizes)[self._last]
        return Pieces(texts, np.diff(sizes, prepend=0))


def _key(address: int) -> bytes:
    """A member's key by address, after a comma (a value no profile names is named so)."""
    return b',"%d":' % address


#: How the tables indexed by address spell an entry (an address past 16 bits, which no wire
#: has, is spelt alone).
_SPELT_BY_ADDRESS = {"starts": param_start, "keys": _key}


def _table(name: str) -> npt.NDArray[Any]:
    if not _tables:
        starts, value_ends = param_tables()
        numbers = [b"%d" % word for word in range(WORDS)]
        for key, texts in (("starts", starts), ("value_ends", value_ends), ("keys", list(map(_key, range(WORDS)))),
                           ("numbers", numbers)):
            _tables[key] = _objects(texts)
            _tables[key + " sizes"] = np.fromiter(map(len, texts), np.int64, len(texts))
    return _tables[name]


def _sizes(name: str) -> npt.NDArray[np.int64]:
    return _table(name + " sizes")


def _by_address(name: str, address: npt.NDArray[np.int64]) -> tuple[npt.NDArray[Any], npt.NDArray[np.int64]]:
    """The entries of table ``name`` at ``address`` and their sizes."""
    within = np.minimum(address, WORDS - 1)
    texts, sizes = _table(name)[within], _sizes(name)[within]
    for place in np.flatnonzero(address >= WORDS).tolist():
        text = _SPELT_BY_ADDRESS[name](int(address[place]))
        texts[place], sizes[place] = text, len(text)
    return texts, sizes


def _objects(items: list[bytes]) -> npt.NDArray[Any]:
    """``items`` as an object array (numpy would make a list of bytes fixed-width strings)."""
    array = np.empty(len(items), object)
    array[:] = items
    return array
