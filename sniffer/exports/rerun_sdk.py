"""The Rerun SDK, imported with the SDK's own log lines about a lost viewer left out.

When a viewer goes away, the SDK's Rust side prints ``ERROR re_grpc_client::write: Write messages
call failed`` and ``ERROR re_sdk::recording_stream: Failed to flush previous sink`` on standard
error, in colour, between rtusniff's own lines, which already say so in words ("the viewer at …
went away; decoding goes on without it"). The SDK reads its log filter (``RUST_LOG``) once, when
it is first imported, so it is set here, before that import, and only where the user has not set
one: ``RUST_LOG=debug rtusniff …`` still shows everything. Every other warning of the SDK (and of
a viewer it spawns) stays.

Import ``rr`` and ``rrb`` from here, never ``rerun`` itself.
"""

from __future__ import annotations

import os

#: The SDK's default level, without the two sources of the lines above.
QUIET_FILTER = "warn,re_grpc_client=off,re_sdk::recording_stream=off"
os.environ.setdefault("RUST_LOG", QUIET_FILTER)

import rerun as rr  # noqa: E402 - after the filter: the SDK reads it at import
import rerun.blueprint as rrb  # noqa: E402

__all__ = ["rr", "rrb"]
