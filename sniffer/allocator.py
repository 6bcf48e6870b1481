"""The C allocator asked to keep the memory a batch freed for the next batch (glibc only).

Every batch of 25 000 frames allocates numpy arrays of a few hundred KB to a few MB and frees
them when the batch is done. glibc gives the free space at the top of its heap back to the
kernel as soon as it exceeds its trim threshold, and serves arrays above its mmap threshold
from fresh mappings; either way the next batch's arrays come back as new pages, which the
kernel zero-fills one fault at a time. ``M_TOP_PAD`` keeps :data:`TOP_PAD` bytes at the top of
the heap when it grows and when it is trimmed, so the next batch's arrays are carved from pages
already there; ``M_MMAP_THRESHOLD`` at :data:`MMAP_THRESHOLD` (the largest glibc's adaptive
threshold reaches by itself) keeps arrays of up to 32 MB on the heap. Both are needed: a pad
set alone turns the adaptive threshold off at 128 KB, and asked for once the heap exists (as
here: the interpreter has started) every array above that came from a fresh mapping, 10 to 15
times the faults of no pad at all. A pad of 16 MB left mixed, steady and USB traffic with more
faults than before; 64 MB fits every benchmark traffic.

With both, a long ``stats`` takes a sixth of the page faults and far less system time, for
the same peak RSS (``/usr/bin/time -v`` with and without, alternating).

Pages of the pad count in the resident set only once written, and they are what the batches'
arrays use anyway: the peak RSS of ``stats`` is the same, of the exports within 10 MB
(``docs/performance.md``). Elsewhere (Windows, macOS, musl) nothing is
asked and nothing changes. Where the environment tunes glibc's allocator itself
(``MALLOC_TOP_PAD_``, ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_``, ``GLIBC_TUNABLES``),
it decides.
"""

from __future__ import annotations

import ctypes
import os
import sys

#: Bytes kept at the top of the heap (see the module docstring for why this size).
TOP_PAD = 64 << 20
#: Allocations above this size get a mapping of their own (see the module docstring).
MMAP_THRESHOLD = 32 << 20
#: ``mallopt``'s parameter numbers (glibc's ``malloc.h``).
M_TOP_PAD, M_MMAP_THRESHOLD = -2, -3
#: Environment variables by which a user tunes glibc's allocator: where one is set, it decides.
TUNING_VARIABLES = ("MALLOC_TOP_PAD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")


def glibc_version() -> str | None:
    """``"glibc 2.36"`` where this process runs on glibc, else ``None``."""
    if not sys.platform.startswith("linux") or not hasattr(os, "confstr"):
        return None
    try:
        version = os.confstr("CS_GNU_LIBC_VERSION")
    except (ValueError, OSError):  # musl and others have no such name
        return None
    return version if version and version.startswith("glibc") else None


def keep_freed_memory() -> bool:
    """Asks glibc for a top pad of :data:`TOP_PAD` bytes and an mmap threshold of
    :data:`MMAP_THRESHOLD`; whether both were set (``False``: not glibc, or the environment
    tunes the allocator: :data:`TUNING_VARIABLES`)."""
    if any(name in os.environ for name in TUNING_VARIABLES) or glibc_version() is None:
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    # The threshold first: the pad alone would fix it at 128 KB for the moment between the two.
    return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(libc.mallopt(M_TOP_PAD, TOP_PAD))
