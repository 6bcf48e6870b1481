"""JSONL records exactly as docs/jsonl-output.md defines them."""

from __future__ import annotations

from typing import Any

import orjson

from decoders.capture import CaptureInfo
from decoders.frame import PROTOCOL_NAMES
from decoders.line import LineSettings
from decoders.message import Message, ParamValue

NS_PER_S = 1e9


def encode_record(record: dict[str, Any]) -> bytes:
    """One record as compact UTF-8 JSON (what ``json.dumps`` with ``separators=(",", ":")`` and
    ``ensure_ascii=False`` writes, a third of the time: every frame passes through here)."""
    return orjson.dumps(record)


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


def device_record(message: Message) -> dict[str, Any]:
    """A slave said what it is (FC 43): the ``device`` record that follows its frame."""
    device = message.device
    assert device is not None
    return {
        "kind": "device",
        "index": message.frame.index,
        "slave": device.slave,
        "vendor": device.vendor,
        "product_code": device.product_code,
        "revision": device.revision,
        "profile": device.profile,
        "applied": device.applied,
    }


def param_record(param: ParamValue) -> dict[str, Any]:
    return {
        "address": param.address,
        "code": param.code,
        "name": param.name,
        "raw": param.raw,
        "value": param.value,
        "unit": param.unit,
    }
