"""The decoded channels served live to the Foxglove app (foxglove-sdk's WebSocket server).

:class:`FoxgloveServerWriter` takes the same message blocks as the MCAP file writer, so the
live stream has the MCAP export's channels and schemas (:class:`~sniffer.exports.mcap_export.
DecodedChannels`): a layout made on a recorded file works live unchanged.

What a slow viewer costs: ``Channel.log`` only queues (the SDK sends from its own threads),
so neither the reader nor the decoding waits for a viewer. The SDK keeps up to ``BACKLOG``
messages per client and drops the oldest beyond them; a client that stops reading is thus
bounded in memory, and one that goes away is forgotten. Channels nobody has subscribed to
are not sent at all (``has_sinks``), with one exception: a channel advertised while a client
watches (a slave's ``/slave/N/params`` when it first carries values) holds its messages until a
client subscribes to it, at most :data:`FRESH_WAIT_S`: the client subscribes on the
advertisement, a round trip later, and would miss the values sent before. This module imports
the SDK (a native library): it is imported only when a stream is asked for. Clients reach the
SDK's server only through :mod:`sniffer.exports.foxglove_gate`, which keeps web pages out.
"""

from __future__ import annotations

import threading
import time
from typing import Any
from urllib.parse import quote

import foxglove
import numpy as np
from foxglove.websocket import ServerListener, StatusLevel

from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.foxglove_gate import Door, FoxgloveGate, inner_host
from sniffer.exports.mcap_writer import HEADER_SIZE, MessageBlock

#: Messages queued per client before the oldest are dropped (about 3 per frame: 20 s of a
#: saturated 115200 Bd line).
BACKLOG = 65536
#: How long the last messages get to reach the clients before the server stops.
CLOSE_GRACE_S = 0.5
#: How long a channel advertised while a client watches holds its messages for a subscriber.
FRESH_WAIT_S = 2.0


class _Subscriptions(ServerListener):
    """The server's listener: sets ``first`` when a client first subscribes to a channel."""

    def __init__(self) -> None:
        self.first = threading.Event()

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.first.set()


class FoxgloveServerWriter:
    """A :class:`~sniffer.exports.mcap_export.MessageWriter` that serves each message to the
    Foxglove clients subscribed to its channel."""

    def __init__(self, host: str, port: int, name: str, door: Door) -> None:
        """Serves on ``host:port`` through a :class:`~sniffer.exports.foxglove_gate.FoxgloveGate`
        that lets in whom ``door`` says; the SDK's own server listens behind it."""
        self._context = foxglove.Context()
        self.subscriptions = _Subscriptions()
        try:
            inner = inner_host()
            self._server = foxglove.start_server(name=name, host=inner, port=0, context=self._context,
                                                 server_listener=self.subscriptions, message_backlog_size=BACKLOG)
        except Exception as exc:  # the SDK raises its own error type
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot start the Foxglove server: {exc}",
                                path="--foxglove") from None
        try:
            self._gate = FoxgloveGate(host, port, (inner, self._server.port), allowed_origins=door.allowed_origins,
                                      token=door.token, tell=door.tell)
        except OSError as exc:
            self._server.stop()
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot serve Foxglove on {host}:{port}: {exc.strerror}",
                                path="--foxglove") from None
        self.host, self.port, self._token = host, self._gate.port, door.token
        self._schemas: list[foxglove.Schema] = []
        self._channels: list[foxglove.Channel] = []
        #: Channels advertised while a client watched, not yet subscribed to: when each was
        #: advertised, and its messages held (payload, log time) in order.
        self._fresh: dict[int, tuple[float, list[tuple[bytes, int]]]] = {}

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}" + (f"/?token={quote(self._token)}" if self._token else "")

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        self._schemas.append(foxglove.Schema(name=name, encoding=encoding, data=data))
        return len(self._schemas)

    def add_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        schema = self._schemas[schema_id - 1]
        channel = foxglove.Channel(topic, schema=schema, message_encoding=message_encoding,
                                         context=self._context, metadata=metadata)
        self._channels.append(channel)
        if self.watched():
            self._fresh[len(self._channels)] = (time.monotonic(), [])
        return len(self._channels)

    def watched(self) -> bool:
        """Whether a client subscribes to any channel (nothing need be built for none)."""
        return any(channel.has_sinks() for channel in self._channels)

    def write(self, block: MessageBlock) -> None:
        """Each message to its channel's subscribers, without the room reserved for MCAP's header;
        a fresh channel's held until a client subscribes to it (see the module docstring)."""
        held = self._settle_fresh()
        listened = np.array([False, *(channel.has_sinks() or index in held
                                      for index, channel in enumerate(self._channels, 1))])
        rows = np.flatnonzero(listened[block.channels])
        if not len(rows):
            return
        data, offsets = bytes(block.rows.data), block.rows.offsets
        starts, ends = (offsets[:-1] + HEADER_SIZE)[rows].tolist(), offsets[1:][rows].tolist()
        channels, times = block.channels[rows].tolist(), block.log_times[rows].tolist()
        for start, end, channel, t_ns in zip(starts, ends, channels, times, strict=True):
            if channel in held:
                held[channel].append((data[start:end], t_ns))
            else:
                self._channels[channel - 1].base.log(data[start:end], t_ns, None)

    def _settle_fresh(self) -> dict[int, list[tuple[bytes, int]]]:
        """The fresh channels still held (their lists take this block's messages): a subscribed
        one gets what it held, in order, and one nobody took within :data:`FRESH_WAIT_S` lets go."""
        now = time.monotonic()
        for index, (advertised, messages) in list(self._fresh.items()):
            channel = self._channels[index - 1]
            if channel.has_sinks():
                for payload, t_ns in messages:
                    channel.base.log(payload, t_ns, None)
            elif now - advertised < FRESH_WAIT_S:
                continue
            del self._fresh[index]
        return {index: messages for index, (_, messages) in self._fresh.items()}

    def status(self, text: str) -> None:
        """A warning every connected client shows (the Foxglove app: in its problems list)."""
        self._server.publish_status(text, StatusLevel.Warning)

    def close(self) -> None:
        """Stops serving, once the SDK's threads had a moment to send what was queued last (it
        offers no way to wait for its queues)."""
        deadline = time.monotonic() + CLOSE_GRACE_S
        while any(messages for _, messages in self._fresh.values()) and time.monotonic() < deadline:
            time.sleep(0.05)  # a subscription on its way: what the channel held goes to it
            self._settle_fresh()
        if self.watched():
            time.sleep(CLOSE_GRACE_S)
        self._server.stop()
        self._gate.close()
