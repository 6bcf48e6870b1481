"""What a decoding gives a frame's records, spelt for all the frames of a batch kept in columns.

A frame the annotator left in columns (``AnnotatedBatch.columnar``: a read, write or answer,
most frames of a bus polled for values that change) has no decoding object. Its params are
spelt from tables by address and raw word, or, where a profile names them
(``ColumnarFrames.names``), from each named value's own JSON and member, made once per value. Its JSONL
record's part from ``params`` to ``remarks``, its MCAP log text after the frame index and its
``/slave/N/params`` members are spelt here from the columns, all the batch's such frames at
once: every piece of every frame is laid out in one numpy object array (the params from the
tables of :mod:`sniffer.encoding.param_text`) with its size beside it, and each frame's pieces
are joined by one ``join``. Built per frame from a decoding
(:func:`~decoders.decoded_batch.columnar_decodings`), the same texts cost an object per
frame and a param run, then a lookup in a memo that new frames always miss.

The texts are exactly those the plain path writes from the decodings: the tests hold them to
it (``tests/property/test_columnar_parts.py``). A ``join`` per frame: one ``join`` of a whole
batch's pieces, cut into views, was slower on registers and on coils alike.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar, cast

import numpy as np
import numpy.typing as npt
import orjson

from decoders.decoded_batch import AnnotatedBatch, ColumnarFrames, ColumnarParams, alike
from decoders.decoded_batch import summaries as base_summaries
from decoders.distinct import distinct
from decoders.message import ROLE_NAMES, MessageBatch
from decoders.runs import spread
from sniffer.encoding.param_text import NO_VALUE_END, PARAM_JSON, PARAM_MEMBERS, WORDS, param_start, param_tables
from sniffer.encoding.rows import Pieces

Text = TypeVar("Text", str, bytes)
#: Params spelt at once (see :func:`_in_slices`).
SLICE_PARAMS = 1 << 16
#: The tables as numpy object arrays (indexed by a column in C), built at first use.
_tables: dict[str, npt.NDArray[Any]] = {}


class ColumnarParts:
    """The texts of the frames of ``columnar`` (``data``: their batch's bytes), each list in
    the order of ``columnar.positions``; each made when first asked for. With ``messages``
    (their batch), frames that read alike (:func:`~decoders.modbus.alike.alike`: a drive's
    unchanged status, a request polled again) are spelt once, and their texts shared."""

    def __init__(self, columnar: ColumnarFrames, data: bytes, messages: MessageBatch | None = None) -> None:
        self.columnar, self._data = columnar, data
        found = None if messages is None else (
            columnar.groups or alike(columnar, data, messages.frames.offsets, messages.role))
        #: The frames spelt, and for each frame its row among them (``None``: each its own).
        self._spelt = columnar if found is None else columnar.take(found.firsts)
        self._inverse: npt.NDArray[np.int64] | None = None if found is None else found.inverse
        self._base_summaries: list[str] | None = None
        self._summaries: list[str] | None = None
        self._params: ColumnarParams | None = None

    @property
    def positions(self) -> npt.NDArray[np.int64]:
        return self.columnar.positions

    @property
    def spelt(self) -> ColumnarFrames:
        """The frames spelt: one per group of frames alike (all of them, where none are grouped)."""
        return self._spelt

    @property
    def inverse(self) -> npt.NDArray[np.int64] | None:
        """For each frame, its row among :attr:`spelt` (``None``: each its own)."""
        return self._inverse

    def summaries(self) -> list[str]:
        return self.each(self._spelt_summaries())

    def base_summaries(self) -> list[str]:
        """The summaries of the frames spelt as their PDUs write them, without what profiles name
        (:func:`~decoders.modbus.columnar_text.summaries`)."""
        if self._base_summaries is None:
            self._base_summaries = base_summaries(self._spelt, self._data)
        return self._base_summaries

    def _spelt_summaries(self) -> list[str]:
        """The summaries of the frames spelt (one per group of frames alike)."""
        if self._summaries is None:
            self._summaries = self._spelt.named_summaries(self.base_summaries())
        return self._summaries

    def record_tails(self) -> Pieces:
        """Each frame's JSONL record part from ``params`` to the end of ``remarks``
        (``FrameRecordEncoder._decoding_part``)."""
        return self._each_piece(self.spelt_record_tails())

    def spelt_record_tails(self) -> Pieces:
        """:meth:`record_tails` of the frames spelt (one per group of frames alike)."""
        summaries = list(map(orjson.dumps, self._spelt_summaries()))
        named = self._named_texts(members=False)
        return _in_slices(self._param_columns(), lambda params, frames: _record_tails(params, summaries[frames], named))

    def log_heads(self, roles: npt.NDArray[np.integer[Any]]) -> list[bytes]:
        """Each frame's log text after its index: `` response: HR = …`` (``roles``: the batch's)."""
        return self.each([f" {ROLE_NAMES[role]}: {summary}".encode()
                           for role, summary in zip(roles[self._spelt.positions].tolist(), self._spelt_summaries(),
                                                    strict=True)])

    def numeric_members(self) -> Pieces:
        """Each frame's values as the members of a JSON object by address, its closing brace
        included (``encode_json(numeric_params(decoding))[1:]``), or ``b""``: it carried none."""
        named = self._named_texts(members=True)
        return self._each_piece(_in_slices(self._param_columns(), lambda params, _: _numeric_members(params, named)))

    def each(self, spelt: list[Text]) -> list[Text]:
        """A text per frame from one per frame spelt (:attr:`spelt`): frames alike share theirs."""
        if self._inverse is None:
            return spelt
        # Taken in C, not by a ``map`` of ``__getitem__``.
        each: list[Text] = np.array(spelt, object)[self._inverse].tolist()
        return each

    def _each_piece(self, spelt: Pieces) -> Pieces:
        return spelt if self._inverse is None else spelt.take(self._inverse)

    def _named_texts(self, *, members: bool) -> npt.NDArray[Any] | None:
        """The JSON (or with ``members``, the params member) of each named value of the frames
        (their :attr:`~decoders.modbus.columnar.ColumnarNames.table`), ``None`` where none is named."""
        names = self._spelt.names
        if names is None:
            return None
        if members:
            return _objects(PARAM_MEMBERS.made([param for param, _ in names.table]))
        return _objects([b"," + text for text in PARAM_JSON.made([param for param, _ in names.table])])

    def _param_columns(self) -> ColumnarParams:
        if self._params is None:
            self._params = self._spelt.params(self._data)
        return self._params


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


def _record_tails(params: ColumnarParams, summaries: list[bytes], named: npt.NDArray[Any] | None) -> Pieces:
    """:meth:`ColumnarParts.record_tails` of the frames of ``params`` (their summaries in JSON;
    ``named``: the JSON of each named value, after a comma)."""
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
    layout.put(after + 3, b',"protocol":"modbus","remarks":[]')
    layout.without_comma(base[sizes > 0] + 1)
    return layout.texts()


def _numeric_members(params: ColumnarParams, named: npt.NDArray[Any] | None) -> Pieces:
    """:meth:`ColumnarParts.numeric_members` of the frames of ``params`` (``named``: each named
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
    """A member's key by address, after a comma (``numeric_params`` names values so)."""
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


_last: tuple[ColumnarFrames, ColumnarParts] | None = None


def columnar_parts(columnar: ColumnarFrames, messages: MessageBatch) -> ColumnarParts:
    """The :class:`ColumnarParts` of ``columnar`` (``messages``: its batch), alike frames spelt
    once: the same one for the sinks that write the same batch (the frame records and the MCAP
    log share the summaries)."""
    global _last  # noqa: PLW0603 - one batch's parts, held until the next batch
    if _last is None or _last[0] is not columnar:
        _last = (columnar, ColumnarParts(columnar, messages.frames.data, messages))
    return _last[1]


Part = TypeVar("Part")


def summary_lines(batch: AnnotatedBatch) -> list[str]:
    """Every kept message's summary line, as its decoding or its columns spell it."""
    return in_columns_too(batch, ColumnarParts.summaries,
                          [decoding.summary for decoding in batch.decoded_at(batch.decoded_positions())])


def in_columns_too(batch: AnnotatedBatch, spell: Callable[[ColumnarParts], Sequence[Part]],
                   parts: list[Part]) -> list[Part]:
    """``parts`` (one per kept message decoded one by one, :meth:`AnnotatedBatch.decoded_positions`),
    with ``spell``'s for the kept frames in columns in their places: one per kept message."""
    columnar = batch.columnar
    if columnar is None or not len(columnar):
        return parts
    placed: list[Part] = [cast(Part, b"")] * len(batch.messages)
    for position, part in zip(batch.decoded_positions(), parts, strict=True):
        placed[position] = part
    for position, part in zip(columnar.positions.tolist(),
                              spell(columnar_parts(columnar, batch.messages)), strict=True):
        placed[position] = part
    return placed if batch.rows is None else list(map(placed.__getitem__, batch.rows.tolist()))
