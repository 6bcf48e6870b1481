"""The door of the Foxglove stream: which WebSocket clients may watch the bus.

A browser lets any web page open a WebSocket to any address, the user's own machine included,
and says which page did in the handshake's ``Origin``. foxglove-sdk's server accepts every
handshake, so a page open in the user's browser could read the decoded bus (and the capture's
name). :class:`FoxgloveGate` listens where the user asked (``--foxglove [HOST:]PORT``), reads
each handshake and relays to the SDK's server only those it lets in:

* no ``Origin`` (a program: Foxglove's desktop app, scripts, ``websockets``);
* an ``Origin`` whose scheme no web page has (``file://``, ``app://``: a desktop shell);
* the Foxglove app's own (:data:`FOXGLOVE_ORIGINS`) and those given with
  ``--foxglove-allow-origin``.

Every other ``http(s)`` origin, and ``null`` (what a sandboxed frame or a ``data:`` page sends),
is refused with ``403`` and one line naming it. With ``--foxglove-token`` a handshake must
also carry ``?token=SECRET`` in its URL (for a port other machines reach).

The SDK's server itself listens on a loopback address no page can guess: a random one of
127.0.0.0/8 where the system routes them all to itself (Linux, Windows), else 127.0.0.1, and a
random port.
"""

from __future__ import annotations

import contextlib
import hmac
import random
import socket
import sys
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from urllib.parse import parse_qs, urlsplit

#: The Foxglove app in a browser (its current and its former address).
FOXGLOVE_ORIGINS = frozenset({"https://app.foxglove.dev", "https://studio.foxglove.dev"})
#: A handshake larger than this is no WebSocket handshake.
MAX_HANDSHAKE_BYTES = 16 * 1024
#: How long a client gets to send its handshake.
HANDSHAKE_TIMEOUT_S = 5.0
RELAY_BYTES = 64 * 1024


@dataclass(frozen=True)
class Door:
    """Whom the stream lets in: origins beyond the Foxglove app's, a token the URL must carry,
    and where a refusal is said."""

    allowed_origins: tuple[str, ...] = ()
    token: str | None = None
    tell: Callable[[str], None] = field(default=lambda text: None)


def inner_host() -> str:
    """A loopback address for the SDK's server that a web page cannot guess."""
    if sys.platform == "darwin":  # macOS answers on 127.0.0.1 only unless told otherwise
        return "127.0.0.1"
    candidate = f"127.{random.randrange(1, 255)}.{random.randrange(1, 255)}.{random.randrange(2, 255)}"
    with socket.socket() as probe:
        try:
            probe.bind((candidate, 0))
        except OSError:
            return "127.0.0.1"
    return candidate


def refusal(origin: str | None, target: str, allowed: frozenset[str], token: str | None) -> str | None:
    """Why a handshake from ``origin`` for ``target`` (its request path) is refused; ``None``
    when it is let in."""
    if origin is not None:
        lowered = origin.strip().lower().rstrip("/")
        web = lowered == "null" or lowered.startswith(("http://", "https://"))
        if web and lowered not in allowed:
            return f"Origin {origin.strip()!r} is not the Foxglove app's (--foxglove-allow-origin lets it in)"
    if token is not None:
        given = parse_qs(urlsplit(target).query).get("token", [""])[0]
        if not hmac.compare_digest(given.encode(), token.encode()):
            return "no or a wrong ?token= (--foxglove-token)"
    return None


class FoxgloveGate:
    """Listens on ``host:port`` and relays the handshakes :func:`refusal` lets in to the SDK's
    server at ``inner``; ``tell`` says each refused origin once."""

    def __init__(self, host: str, port: int, inner: tuple[str, int], *, allowed_origins: Iterable[str] = (),
                 token: str | None = None, tell: Callable[[str], None] = lambda text: None) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listener = socket.create_server((host, port), family=family)
        self.port: int = self._listener.getsockname()[1]
        self._inner = inner
        self._allowed = FOXGLOVE_ORIGINS | {origin.lower().rstrip("/") for origin in allowed_origins}
        self._token = token
        self._tell = tell
        self._told: set[str] = set()
        self._open: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._closed = False
        threading.Thread(target=self._accept, name="foxglove-gate", daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return  # closed
            threading.Thread(target=self._admit, args=(client,), daemon=True).start()

    def _admit(self, client: socket.socket) -> None:
        try:
            head = self._handshake(client)
        except OSError:
            client.close()
            return
        why = self._judge(head)
        if why is not None:
            self._refuse(client, why)
            return
        try:
            inner = socket.create_connection(self._inner, timeout=HANDSHAKE_TIMEOUT_S)
            inner.settimeout(None)
            inner.sendall(head)
        except OSError:
            client.close()
            return
        with self._lock:
            if self._closed:
                client.close()
                inner.close()
                return
            self._open |= {client, inner}
        threading.Thread(target=self._relay, args=(inner, client), daemon=True).start()
        self._relay(client, inner)

    def _handshake(self, client: socket.socket) -> bytes:
        """The request head, up to its blank line (or what came before the limit or the timeout)."""
        client.settimeout(HANDSHAKE_TIMEOUT_S)
        head = b""
        while b"\r\n\r\n" not in head and len(head) < MAX_HANDSHAKE_BYTES:
            part = client.recv(4096)
            if not part:
                break
            head += part
        client.settimeout(None)
        return head

    def _judge(self, head: bytes) -> str | None:
        if b"\r\n\r\n" not in head:
            return "no complete WebSocket handshake"
        lines = head.split(b"\r\n\r\n", 1)[0].decode("latin-1").split("\r\n")
        parts = lines[0].split(" ")
        if len(parts) != 3 or parts[0] != "GET":
            return "not a WebSocket handshake"
        origins = [value.strip() for name, _, value in (line.partition(":") for line in lines[1:])
                   if name.strip().lower() == "origin"]
        if len(origins) > 1:
            return "two Origin headers"
        return refusal(origins[0] if origins else None, parts[1], self._allowed, self._token)

    def _refuse(self, client: socket.socket, why: str) -> None:
        body = f"rtusniff: refused: {why}\n".encode()
        with contextlib.suppress(OSError):
            client.sendall(b"HTTP/1.1 403 Forbidden\r\nContent-Type: text/plain\r\nConnection: close\r\n"
                           + f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
        client.close()
        with self._lock:
            first = why not in self._told
            self._told.add(why)
        if first:
            self._tell(f"Foxglove: refused a client: {why}")

    def _relay(self, source: socket.socket, target: socket.socket) -> None:
        """Bytes from ``source`` to ``target`` until either ends; then both are closed."""
        try:
            while data := source.recv(RELAY_BYTES):
                target.sendall(data)
        except OSError:
            pass
        finally:
            for end in (source, target):
                with contextlib.suppress(OSError):
                    end.shutdown(socket.SHUT_RDWR)
                end.close()
            with self._lock:
                self._open -= {source, target}

    def close(self) -> None:
        with self._lock:
            self._closed = True
            open_now = list(self._open)
        with contextlib.suppress(OSError):
            self._listener.shutdown(socket.SHUT_RDWR)  # wakes the accepting thread (Linux)
        with contextlib.suppress(OSError):
            self._listener.close()
        for connection in open_now:
            with contextlib.suppress(OSError):
                connection.shutdown(socket.SHUT_RDWR)
