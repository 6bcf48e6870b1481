"""A Foxglove WebSocket client for the tests: it speaks the protocol as the Foxglove app does.

It connects with the ``foxglove.sdk.v1`` subprotocol, subscribes to every channel the server
advertises (also those advertised later: a slave's params), and keeps each message by topic:
``(log time, payload)``. It runs its own asyncio loop in a thread, so a test can start it,
drive rtusniff, and read what arrived.
"""

from __future__ import annotations

import asyncio
import json
import struct
import threading
import time
from collections import defaultdict
from typing import Any

import websockets

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 1


class FoxgloveClient:
    def __init__(self, url: str, *, read: bool = True, origin: str | None = None) -> None:
        """``read=False``: connect and subscribe, then never read again (a viewer that hangs);
        ``origin``: the ``Origin`` a browser would send for the page that connects."""
        self.url, self._read, self._origin = url, read, origin
        self.channels: dict[int, dict[str, Any]] = {}
        self.messages: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
        #: When each message arrived (time.monotonic), by topic.
        self.arrivals: dict[str, list[float]] = defaultdict(list)
        #: When each message arrived (time.time_ns: comparable with a live capture's frame times).
        self.arrivals_ns: dict[str, list[int]] = defaultdict(list)
        self.statuses: list[dict[str, Any]] = []
        self.server_info: dict[str, Any] | None = None
        self.subscribed = threading.Event()
        #: When the first subscription was sent (time.monotonic): a replay that waits for a
        #: viewer starts after it.
        self.subscribed_at: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self.error: BaseException | None = None

    def __enter__(self) -> FoxgloveClient:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)

    def json(self, topic: str) -> list[dict[str, Any]]:
        return [json.loads(payload) for _, payload in self.messages[topic]]

    def wait_for(self, topic: str, count: int, timeout: float = 30) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if len(self.messages[topic]) >= count:
                return True
            time.sleep(0.05)
        return False

    async def _run(self) -> None:
        try:
            deadline = time.monotonic() + 30
            while True:  # the server may not be up yet
                try:
                    connection = await websockets.connect(self.url, subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
                                                          max_size=None, origin=self._origin)  # type: ignore[arg-type]
                    break
                except OSError:
                    if time.monotonic() > deadline or self._stop.is_set():
                        raise
                    await asyncio.sleep(0.1)
            async with connection as ws:
                while not self._stop.is_set():
                    if not self._read and self.subscribed.is_set():
                        await asyncio.sleep(0.1)  # connected and subscribed, reading nothing more
                        continue
                    try:
                        message = await asyncio.wait_for(ws.recv(), 0.2)
                    except TimeoutError:
                        continue
                    except websockets.ConnectionClosed:
                        return
                    await self._handle(ws, message)
        except BaseException as exc:
            self.error = exc

    async def _handle(self, ws: Any, message: str | bytes) -> None:
        if isinstance(message, bytes):
            if message[0] == MESSAGE_DATA:
                subscription, t_ns = struct.unpack_from("<IQ", message, 1)
                topic = self.channels[subscription]["topic"]
                self.messages[topic].append((t_ns, message[13:]))
                self.arrivals[topic].append(time.monotonic())
                self.arrivals_ns[topic].append(time.time_ns())
            return
        record = json.loads(message)
        if record["op"] == "serverInfo":
            self.server_info = record
        elif record["op"] == "advertise":
            new = [channel for channel in record["channels"] if channel["id"] not in self.channels]
            for channel in new:
                self.channels[channel["id"]] = channel  # subscription id = channel id
            await ws.send(json.dumps({"op": "subscribe",
                                      "subscriptions": [{"id": c["id"], "channelId": c["id"]} for c in new]}))
            if not self.subscribed.is_set():
                self.subscribed_at = time.monotonic()
            self.subscribed.set()
        elif record["op"] == "status":
            self.statuses.append(record)
