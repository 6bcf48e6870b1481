"""Frames that differ from one decoded before only in their values, decoded from their values.

A drive answers the same read with new values and a master writes new setpoints to the same
registers: each such frame is new to the annotator's memo, and the plain path parses it, finds
its params' runs, its slave's profile, each register's namer and its limit remarks anew, though
all of that but the values is what it was for the frame before. Here the frames of one *shape*
share what the plain path made of one of them:

* a shape is a frame's role, the bytes before its values, its length, the answer context of its
  request (:func:`decoders.modbus.annotate.answer_context`) and the profiles' version; it has
  one only where its CRC is good, it is Modbus, and it is one of: an FC 3, 4 or 23 answer
  (values from byte 3), an FC 6 write or its echo (byte 4), an FC 16 write (byte 7) or an FC 23
  request (byte 11);
* the first two frames of a shape are decoded by the plain path (most shapes of a master
  polling ever other registers never come again); the :class:`Shape` made of the second keeps
  the PDU's other fields, its params' namers (:meth:`~decoders.profiles.apply.ProfileApplier.value_namers`)
  and its remarks, which depend on the function and counts alone. A shape whose values would
  teach the profiles (a scanner address register) is never kept;
* a frame of a known shape is its values unpacked, its PDU rebuilt, its summary written by the
  PDU's own ``summary()`` and its values named by the shape's namers as
  :meth:`~decoders.profiles.apply.ProfileApplier.named_by` names them.

A shape is kept only once it has said, of that frame's own values, exactly what the plain path
said; the tests hold every frame to the plain path (``tests/property/test_annotation_cache.py``).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import partial

from decoders.frame import MODBUS
from decoders.message import ROLE_CODE, Decoding, Role
from decoders.modbus.param_runs import LazyParams
from decoders.modbus.pdu import Pdu, ReadWriteRequest, RegistersResponse, WriteRegistersRequest, WriteSingle
from decoders.modbus.pdu_text import HEX_WORDS_SHOWN, hex_words
from decoders.profiles.apply import FrameFacts, ProfileApplier
from decoders.profiles.naming import AddressNamer, summary_with

#: Where a frame's values begin, by role code and function.
VALUES_FROM = {
    **{(ROLE_CODE[Role.RESPONSE], function): 3 for function in (3, 4, 23)},
    **{(ROLE_CODE[role], 6): 4 for role in (Role.REQUEST, Role.BROADCAST, Role.RESPONSE)},
    **{(ROLE_CODE[role], 16): 7 for role in (Role.REQUEST, Role.BROADCAST)},
    **{(ROLE_CODE[role], 23): 11 for role in (Role.REQUEST, Role.BROADCAST)},
}
#: Shapes kept; all are let go at once past it (a bus has tens, a damaged line more).
KEPT_SHAPES = 4096
#: Frames looked up between two looks at whether looking up is worth it, the share of them of
#: a shape seen before it takes, and the frames not looked up when it is not.
WINDOW, REPEATS_WORTH_IT, REST = 4096, 1 / 16, 1 << 16
#: A frame's shape: its role code, the bytes before its values, its length, its request's answer
#: context and the profiles' version.
ShapeKey = tuple[int, bytes, int, object, int]
#: A frame's decoding and the answer context its answer reads.
Decoded = tuple[Decoding, "tuple[object, ...] | None"]
#: A frame's PDU summary, from its bytes, where its values begin and its values.
SummaryWriter = Callable[[bytes, int, tuple[int, ...]], str]


class Shape:
    """What the frames of one shape share: how to rebuild their PDU from their values, how to
    write their PDU's summary from their bytes (:func:`summary_writer`), their params' namers
    (``None``: no profile adds to them, the params are named when read), the params named without
    a value after the values (an FC 23 request's read), the remarks."""

    __slots__ = ("context", "generation", "namers", "pdu_of", "remarks", "summary_of", "unpack", "unvalued")

    def __init__(self, unpack: Callable[[bytes, int], tuple[int, ...]], pdu_of: Callable[[tuple[int, ...]], Pdu],
                 summary_of: SummaryWriter, context: tuple[object, ...] | None, *,
                 named: tuple[list[AddressNamer], int] | None = None, unvalued: int = 0,
                 remarks: tuple[str, ...] = ()) -> None:
        self.unpack, self.pdu_of, self.summary_of, self.context = unpack, pdu_of, summary_of, context
        self.namers: list[AddressNamer] | None = None if named is None else named[0]
        self.generation = 0 if named is None else named[1]
        self.unvalued, self.remarks = unvalued, remarks

    def decode(self, data: bytes, start: int, request: Pdu | None, profiles: ProfileApplier | None) -> Decoding | None:
        """The decoding of ``data`` (a frame of this shape whose values begin at ``start``);
        ``None`` where the namers were let go since."""
        values = self.unpack(data, start)
        pdu = self.pdu_of(values)
        if self.namers is None:
            return LazyParams(self.summary_of(data, start, values), pdu, request)
        assert profiles is not None
        raws = values + (None,) * self.unvalued if self.unvalued else values
        named = profiles.named_by(self.namers, raws, self.generation)
        if named is None:
            return None
        params, shown = named
        return Decoding(summary_with(self.summary_of(data, start, values), shown), tuple(params), pdu, self.remarks)


class ValueShapes:
    """The shapes seen (:class:`Shape`, or ``None``: never kept), for one annotator.

    Where shapes do not repeat (a master reading ever other registers), looking them up costs
    for nothing: after every :data:`WINDOW` frames looked up, if fewer than a
    :data:`REPEATS_WORTH_IT` share of them were of a shape seen before, the next
    :data:`REST` frames are not looked up (nor learnt from)."""

    def __init__(self, profiles: ProfileApplier | None) -> None:
        self._profiles = profiles
        self._shapes: dict[ShapeKey, Shape | None] = {}
        #: Shapes seen once (kept from their second frame on: most of a polling master's reads
        #: of ever other registers are never repeated, and would cost a shape each for nothing).
        self._seen_once: set[ShapeKey] = set()
        #: The applier's generation of namers the shapes hold (all are let go with them: a
        #: shape holding namers let go would keep their named values too).
        self._generation = 0
        #: The shape of the frame :meth:`decode` last found none for, and where its values begin.
        self._missed: tuple[ShapeKey, int] | None = None
        self._looked = self._repeats = self._resting = 0

    def decode(self, key: tuple[int, int, bytes, object, int], crc_ok: bool, request: Pdu | None) -> Decoded | None:
        """The decoding of the frame of the annotator's ``key`` if its shape is known."""
        self._missed = None
        if self._resting:
            self._resting -= 1
            return None
        role, protocol, data = key[0], key[1], key[2]
        start = VALUES_FROM.get((role, data[1])) if len(data) > 4 and crc_ok and protocol == MODBUS else None
        if start is None:
            return None
        if self._profiles is not None and self._profiles.generation != self._generation:
            self._shapes.clear()
            self._generation = self._profiles.generation
        self._looked += 1
        if self._looked >= WINDOW:
            if self._repeats < REPEATS_WORTH_IT * self._looked:
                self._resting = REST
            self._looked = self._repeats = 0
        shape_key = (role, data[:start], len(data), key[3], key[4])
        shape = self._shapes.get(shape_key)
        if shape is None:
            self._missed = (shape_key, start)
            return None
        self._repeats += 1
        decoding = shape.decode(data, start, request, self._profiles)
        return None if decoding is None else (decoding, shape.context)

    def learn(self, key: tuple[int, int, bytes, object, int], facts: FrameFacts, request: Pdu | None,
              decoded: Decoded, version: int) -> None:
        """Keep the shape of the frame :meth:`decode` was just asked for and found none for
        (``key``: the annotator's; ``facts``: the applier's of it), whose plain decoding is
        ``decoded``, made at the profiles' ``version``."""
        missed, self._missed = self._missed, None
        if missed is None or version != key[4]:  # no shape, or the frame taught the profiles something
            return
        shape_key, start = missed
        if shape_key in self._shapes:  # never kept (None)
            return
        if shape_key not in self._seen_once:
            if len(self._seen_once) >= KEPT_SHAPES:
                self._seen_once.clear()
            self._seen_once.add(shape_key)
            return
        self._repeats += 1
        self._seen_once.discard(shape_key)
        if len(self._shapes) >= KEPT_SHAPES:
            self._shapes.clear()
        self._shapes[shape_key] = None
        data = key[2]
        shape = self._shape(data, start, facts, decoded)
        if shape is not None and _said(shape.decode(data, start, request, self._profiles)) == _said(decoded[0]):
            self._shapes[shape_key] = shape

    def _shape(self, data: bytes, start: int, facts: FrameFacts, decoded: Decoded) -> Shape | None:
        decoding, context = decoded
        pdu, words = decoding.pdu, (len(data) - start - 2) // 2
        pdu_of = _rebuilt(pdu)
        if pdu_of is None or pdu is None or words < 1 or decoding.device is not None or decoding.uss is not None:
            return None
        summary_of = summary_writer(pdu, words)
        if summary_of is None:
            return None
        unpack = struct.Struct(f">{words}H").unpack_from
        if type(decoding) is LazyParams:
            return Shape(unpack, pdu_of, summary_of, context)
        if self._profiles is None:
            return None
        addresses = [param.address for param in decoding.params]
        unvalued = len(addresses) - words
        named = self._profiles.value_namers(facts, addresses) if unvalued >= 0 else None
        if named is None:
            return None
        return Shape(unpack, pdu_of, summary_of, context, named=named, unvalued=unvalued, remarks=decoding.remarks)


def _rebuilt(pdu: Pdu | None) -> Callable[[tuple[int, ...]], Pdu] | None:
    """How to build ``pdu`` again with other values (``None``: not a PDU of the shapes)."""
    match pdu:
        case RegistersResponse(function=function, byte_count=byte_count):
            return partial(RegistersResponse, function, byte_count)
        case WriteSingle(function=6, address=address):
            return lambda values: WriteSingle(6, address, values[0])
        case WriteRegistersRequest(address=address, count=count):
            return partial(WriteRegistersRequest, address, count)
        case ReadWriteRequest(read_address=read, read_count=reads, write_address=write, write_count=writes):
            return partial(ReadWriteRequest, read, reads, write, writes)
    return None


def summary_writer(pdu: Pdu, words: int) -> SummaryWriter | None:
    """How to write the summary of a PDU of ``pdu``'s shape (``words`` values) from a frame's
    bytes: what the summary says of the values is their hex words (:func:`hex_words`), which
    are the frame's own bytes in hex, or an FC 6 value in decimal and hex; the rest is the
    shape's. Building the words from the bytes costs a third of what ``pdu.summary()`` does,
    which formats the values anew (``None``: a summary not written so)."""
    text = pdu.summary()
    if isinstance(pdu, WriteSingle):
        head = text.removesuffix(f"{pdu.value} (0x{pdu.value:04X})")
        return None if head == text else lambda _data, _start, values: f"{head}{values[0]} (0x{values[0]:04X})"
    values: tuple[int, ...] = getattr(pdu, "values", ())
    if len(values) != words:
        return None
    shown_bytes = 2 * min(words, HEX_WORDS_SHOWN)
    written = hex_words(values)
    at = text.rfind(written)
    if at < 0:
        return None
    head, tail = text[:at], text[at + len(hex_words(values[:HEX_WORDS_SHOWN])) :]
    return lambda data, start, _values: head + data[start : start + shown_bytes].hex(" ", 2).upper() + tail


def _said(decoding: Decoding | None) -> tuple[object, ...] | None:
    """All a decoding says (a :class:`LazyParams`' params as the runs it would name them from:
    a read of 125 registers would be 125 objects)."""
    if decoding is None:
        return None
    params = decoding.runs if isinstance(decoding, LazyParams) else decoding.params
    return (type(decoding), decoding.summary, params, decoding.pdu, decoding.remarks, decoding.device, decoding.uss)
