"""The ``params`` text of a register or coil run three ways, side by side: ns per param.

    python -m benchmarks.bench_param_text

``tables`` is what :mod:`sniffer.encoding.param_text` does (address starts and value ends
formatted once for all 65 536 words, slices joined); ``template``: one ``%``-template per run
length, filled in C; ``dict``: value ends kept in a dict as values come (the former way). Each
writes the JSON array as UTF-8, as a record takes it.
Values: ``none`` (a read request), ``random`` (every value new: the polling benchmark),
``steady`` (a few values again and again: a plant), ``bits`` (coils).
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable
from itertools import chain

from decoders.modbus.param_runs import ParamRun
from sniffer.encoding import param_text

RUNS_PER_CASE = 20_000
LENGTHS = (1, 2, 4, 8, 16, 32, 64, 125)
KINDS = ("none", "random", "steady", "bits")
_VALUED = b'{"address":%d,"code":null,"name":null,"raw":%d,"value":%d,"unit":null}'
_UNVALUED = b'{"address":%d,"code":null,"name":null,"raw":null,"value":null,"unit":null}'
_templates: dict[tuple[int, bool], bytes] = {}
_ends: dict[int, bytes] = {}


def _tables(run: ParamRun) -> bytes:
    return param_text.runs_json((run,))


def _template(run: ParamRun) -> bytes:
    address, count, values = run
    key = (count, values is None)
    template = _templates.get(key)
    if template is None:
        template = _templates[key] = b"[" + b",".join([_UNVALUED if values is None else _VALUED] * count) + b"]"
    if values is None:
        return template % tuple(range(address, address + count))
    return template % tuple(chain.from_iterable(zip(range(address, address + count), values, values, strict=True)))


def _dict_end(value: int) -> bytes:
    end = _ends.get(value)
    if end is None:
        end = _ends[value] = b'%d,"value":%d,"unit":null}' % (value, value)
    return end


def _dict(run: ParamRun) -> bytes:
    address, count, values = run
    pieces: list[bytes] = [b""] * (2 * count)
    pieces[::2] = param_text._starts[address : address + count]  # the same address starts
    pieces[1::2] = [param_text._NO_VALUE] * count if values is None else list(map(_dict_end, values))
    return b"[" + b"".join(pieces)[1:] + b"]"


def _values(kind: str, count: int, rng: random.Random) -> tuple[int, ...] | None:
    if kind == "none":
        return None
    if kind == "random":
        return tuple(rng.randrange(1 << 16) for _ in range(count))
    if kind == "steady":
        return tuple(rng.choice((0, 1, 500, 1500, 3201)) for _ in range(count))
    return tuple(rng.randrange(2) for _ in range(count))


def _ns_per_param(write: Callable[[ParamRun], bytes], runs: list[ParamRun], count: int) -> float:
    start = time.perf_counter()
    for run in runs:
        write(run)
    return (time.perf_counter() - start) / len(runs) / count * 1e9


def main() -> None:
    rng = random.Random(1)
    _tables(ParamRun(0, 1))  # the tables are built at first use, not timed
    ways: dict[str, Callable[[ParamRun], bytes]] = {"tables": _tables, "template": _template, "dict": _dict}
    print(f"{'params':>6} {'values':>7}" + "".join(f"{name + ' ns':>12}" for name in ways))
    for count in LENGTHS:
        for kind in KINDS:
            runs = [ParamRun(rng.randrange((1 << 16) - count), count, _values(kind, count, rng))
                    for _ in range(RUNS_PER_CASE)]
            for run in runs[:50]:
                assert len({write(run) for write in ways.values()}) == 1
            figures = "".join(f"{_ns_per_param(write, runs, count):>12.0f}" for write in ways.values())
            print(f"{count:>6} {kind:>7}{figures}")


if __name__ == "__main__":
    main()
