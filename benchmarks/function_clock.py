"""Runs one rtusniff command and says how much CPU its main thread spent in the functions named.

    PYTHONPATH=TREE python benchmarks/function_clock.py MODULE:QUALNAME[,…] COMMAND ARGS…

e.g. ``decoders.modbus.annotate:find_columnar,sniffer.exports.parquet_summaries:summaries export
CAPTURE --parquet DIR -q``. Each function is replaced where it is defined and wherever a module
already imported holds it by name (``from … import``: the same object), and its calls are timed
by ``time.thread_time()``; a function that calls another named counts that one's time too.
Prints, as the last line on standard error, ``QUALNAME=seconds`` for each, and ``main=`` the
thread's CPU from the command's start. Run it on two trees alternating, as the figures of
``docs/performance.md`` were: one run says little on a shared machine.
"""

from __future__ import annotations

import importlib
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

#: Seconds of the main thread's CPU spent in each function timed, by its qualified name.
SPENT: defaultdict[str, float] = defaultdict(float)


def _clocked(name: str, function: Callable[..., Any]) -> Callable[..., Any]:
    def clocked(*args: Any, **kwargs: Any) -> Any:
        started = time.thread_time()
        try:
            return function(*args, **kwargs)
        finally:
            SPENT[name] += time.thread_time() - started

    return clocked


def clock(spec: str) -> None:
    """Times the function ``MODULE:QUALNAME`` from now on."""
    module_name, qualname = spec.split(":")
    owner: Any = importlib.import_module(module_name)
    *path, name = qualname.split(".")
    for part in path:
        owner = getattr(owner, part)
    function = getattr(owner, name)
    clocked = _clocked(qualname, function)
    setattr(owner, name, clocked)
    if not path:  # a module function: also where it was imported by name
        for module in list(sys.modules.values()):
            if module is not None and getattr(module, name, None) is function:
                setattr(module, name, clocked)


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    for spec in argv[0].split(","):
        clock(spec)
    from sniffer.cli import main as rtusniff  # the tree on PYTHONPATH

    started = time.thread_time()
    try:
        return rtusniff(argv[1:])
    finally:
        spent = " ".join(f"{name}={seconds:.3f}" for name, seconds in SPENT.items())
        print(f"{spent} main={time.thread_time() - started:.2f}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
