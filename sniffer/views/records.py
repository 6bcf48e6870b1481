"""JSONL records exactly as docs/jsonl-output.md defines them."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import numpy.typing as npt
import orjson

from decoders.capture import CaptureInfo
from decoders.frame import PROTOCOL_NAMES, FrameFlag, flag_set
from decoders.line import LineSettings
from decoders.memo import Memo
from decoders.message import (
    NONE,
    ROLE_ORDER,
    AnnotatedBatch,
    Decoding,
    DeviceIdentity,
    Message,
    MessageBatch,
    ParamValue,
)
from decoders.modbus.annotate import KEPT_DECODINGS

NS_PER_S = 1e9


def encode_record(record: dict[str, Any]) -> str:
    """One record as compact JSON, exactly what ``json.dumps`` writes with
    ``separators=(",", ":")`` and ``ensure_ascii=False`` (scripts compare outputs)."""
    return json.dumps(record, ensure_ascii=False, separators=(",", ":"))


def encode_json(value: object) -> bytes:
    """Compact UTF-8 JSON, fast (orjson), where no one compares bytes (MCAP messages).
    Numbers may be spelt differently from ``json.dumps``: ``0.00005`` for ``5e-05``."""
    return orjson.dumps(value)


def _spelt_alike(params: tuple[ParamValue, ...]) -> bool:
    """Whether orjson writes the params' numbers as ``json.dumps`` does: floats differ only
    where ``repr`` switches to an exponent."""
    return all(type(p.value) is not float or p.value == 0 or 1e-4 <= abs(p.value) < 1e16 for p in params)


def capture_record(source: str, info: CaptureInfo, line: LineSettings) -> dict[str, Any]:
    """The first record: what the capture is and how far its times can be trusted."""
    return {
        "kind": "capture",
        "source": source,
        "line": line.format(),
        "timing": info.timing.value,
        "char_time_s": line.char_time_ns / NS_PER_S,
        "t1_5_s": line.t1_5_ns / NS_PER_S,
        "t3_5_s": line.t3_5_ns / NS_PER_S,
        "notes": list(info.notes),
    }


def frame_record(message: Message) -> dict[str, Any]:
    """One frame record; ``t_ns``/``t_end_ns`` add the exact integer times."""
    frame = message.frame
    return {
        "kind": "frame",
        "index": frame.index,
        "t": frame.t_start_ns / NS_PER_S,
        "t_end": frame.t_end_ns / NS_PER_S,
        "t_ns": frame.t_start_ns,
        "t_end_ns": frame.t_end_ns,
        "hex": frame.data.hex(),
        "crc_ok": frame.crc_ok,
        "slave": message.slave,
        "function": message.function,
        "role": message.role.value,
        "exception_code": message.exception_code,
        "flags": message.flags.names,
        "request_index": message.request_index,
        "latency_s": None if message.latency_ns is None else message.latency_ns / NS_PER_S,
        "params": [param_record(p) for p in message.params],
        "summary": message.summary,
        "protocol": PROTOCOL_NAMES[frame.protocol],
        "remarks": list(message.remarks),
    }


_PROTOCOL_JSON = {code: f'"{name}"' for code, name in PROTOCOL_NAMES.items()}
_FLAGS_JSON = [encode_json(list(flag_set(value).names)).decode() for value in range(1 << len(FrameFlag))]


class FrameRecordEncoder:
    """Frame records as JSON text, exactly ``encode_record(frame_record(m))``, fast.

    Every frame passes through here. What a decoding determines (bytes, role, params,
    summary, remarks) is encoded once per :class:`Decoding` (the annotator shares one
    between repeats); times, flags and pairing come from the batch's columns. Floats
    are written as ``repr`` writes them, which is what ``json.dumps`` does.
    """

    def __init__(self) -> None:
        # As many as the annotator keeps decodings: a repeat finds its parts.
        self._parts: Memo[Decoding, tuple[str, str]] = Memo(KEPT_DECODINGS)

    def encode_batch(self, batch: AnnotatedBatch) -> list[str]:
        """The kept messages' frame records, from the columns: no message objects, and each
        column formatted by one ``repr``."""
        messages, frames = batch.messages, batch.messages.frames
        positions = batch.positions()
        requests, latencies = messages.request_index[positions], messages.latency_ns[positions]
        columns = zip(
            _texts(frames.t_start_ns[positions] / NS_PER_S),
            _texts(frames.t_end_ns[positions] / NS_PER_S),
            _texts(frames.t_start_ns[positions]),
            _texts(frames.t_end_ns[positions]),
            messages.flags[positions].tolist(),
            _or_null(_texts(requests), requests),
            _or_null(_texts(latencies / NS_PER_S), latencies),
            strict=True,
        )
        first, decodings, facts, lines = frames.first_index, batch.decodings, _FrameFacts(messages), []
        for position, (t, t_end, t_ns, t_end_ns, flags, request, latency) in zip(positions, columns, strict=True):
            decoding = decodings[position]
            parts = self._parts.get(decoding) or self._frame_parts(facts, position, decoding)
            lines.append(
                f'{{"kind":"frame","index":{first + position},"t":{t},"t_end":{t_end},"t_ns":{t_ns},'
                f'"t_end_ns":{t_end_ns},{parts[0]},"flags":{_FLAGS_JSON[flags]},"request_index":{request},'
                f'"latency_s":{latency},{parts[1]}}}'
            )
        return lines

    def _frame_parts(self, facts: _FrameFacts, position: int, decoding: Decoding) -> tuple[str, str]:
        """A record's parts that a decoding determines: from ``hex`` to ``exception_code``, and
        from ``params`` to the end (the annotator shares a decoding only between frames with the
        same bytes, role and protocol)."""
        data, crc_ok, slave, function, role, code, protocol = facts(position)
        record = {"params": [param_record(p) for p in decoding.params], "summary": decoding.summary}
        text = encode_json(record).decode() if _spelt_alike(decoding.params) else encode_record(record)
        params_summary = text[1:-1]
        remarks = encode_json(list(decoding.remarks)).decode()
        parts = (
            f'"hex":"{data.hex()}","crc_ok":{"true" if crc_ok else "false"},'
            f'"slave":{"null" if slave == NONE else slave},"function":{"null" if function == NONE else function},'
            f'"role":"{ROLE_ORDER[role].value}","exception_code":{"null" if code == NONE else code}',
            f'{params_summary},"protocol":{_PROTOCOL_JSON[protocol]},"remarks":{remarks}',
        )
        self._parts.put(decoding, parts)
        return parts


class _FrameFacts:
    """What a frame record takes from a batch's columns besides its times, by position: the
    columns are read into lists at the first frame whose decoding is new (none, for a batch
    of repeats)."""

    def __init__(self, batch: MessageBatch) -> None:
        self._batch = batch
        self._lists: tuple[list[Any], ...] | None = None

    def __call__(self, position: int) -> tuple[bytes, bool, int, int, int, int, int]:
        if self._lists is None:
            batch, frames = self._batch, self._batch.frames
            self._lists = tuple(column.tolist() for column in (
                frames.offsets, frames.crc_ok, batch.slave, batch.function, batch.role, batch.exception_code,
                frames.protocols()))
        offsets, crc_ok, slave, function, role, code, protocol = self._lists
        data = self._batch.frames.data[offsets[position] : offsets[position + 1]]
        return data, crc_ok[position], slave[position], function[position], role[position], code[position], \
            protocol[position]


def device_record(index: int, device: DeviceIdentity) -> dict[str, Any]:
    """A slave said what it is (FC 43): the ``device`` record that follows its frame ``index``."""
    return {
        "kind": "device",
        "index": index,
        "slave": device.slave,
        "vendor": device.vendor,
        "product_code": device.product_code,
        "revision": device.revision,
        "profile": device.profile,
        "applied": device.applied,
    }


def _texts(column: npt.NDArray[Any]) -> list[str]:
    """Each number of ``column`` as ``repr`` (so ``json.dumps``) writes it. One ``repr`` of the
    whole list formats in C what a loop would format one by one."""
    return repr(column.tolist())[1:-1].split(", ") if len(column) else []


def _or_null(texts: list[str], column: npt.NDArray[np.int64]) -> list[str]:
    """``texts`` with null where ``column`` holds ``NONE``."""
    for position in np.flatnonzero(column == NONE).tolist():
        texts[position] = "null"
    return texts


def param_record(param: ParamValue) -> dict[str, Any]:
    return {
        "address": param.address,
        "code": param.code,
        "name": param.name,
        "raw": param.raw,
        "value": param.value,
        "unit": param.unit,
    }
