"""Sending to a live Rerun viewer from a thread of its own (:class:`LiveSender`).

Each entity sent is a call into Rerun's SDK with a fixed cost (building Arrow columns in
Python, then the SDK's own work): on a busy line a round of sends takes tens of
milliseconds. The decoding hands a round over and goes on, so frames reach the other
outputs (the view, Foxglove) without waiting for Rerun. Where the SDK falls behind by more
than ``MAX_PENDING`` rounds, a round is skipped and its rows counted: a live view may lose
values, the recording never does (it is written by the recorder, not from here).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

#: Rounds waiting for the sending thread before one is skipped (about a second of them).
MAX_PENDING = 4


class LiveSender:
    def __init__(self, send: Callable[[list[Any]], object]) -> None:
        """``send``: sends one round's items (called in the sending thread, in order)."""
        self._send = send
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="rtusniff-rerun")
        self._pending: deque[Future[object]] = deque()
        #: Rows skipped because the sending thread had fallen behind.
        self.skipped_rows = 0

    def submit(self, items: list[Any], rows: int) -> None:
        """Hand a round over (``rows``: what it holds, counted if it is skipped)."""
        while self._pending and self._pending[0].done():
            self._pending.popleft().result()  # a failure in the SDK is raised here, in the caller's thread
        if len(self._pending) >= MAX_PENDING:
            self.skipped_rows += rows
            return
        if items:
            self._pending.append(self._worker.submit(self._send, items))

    def abandon(self) -> None:
        """Stop: rounds not begun are dropped, the one being sent is not waited for."""
        for pending in self._pending:
            pending.cancel()
        self._pending.clear()
        self._worker.shutdown(wait=False, cancel_futures=True)

    def close(self) -> None:
        """Wait for what was handed over to be sent."""
        try:
            while self._pending:
                self._pending.popleft().result()
        finally:
            self._worker.shutdown(wait=True)
