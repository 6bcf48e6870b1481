"""Serial lines without hardware: socat pseudo-terminal pairs, a copying relay, a pymodbus slave.

Topology of an end-to-end test::

    pymodbus master ⇄ [pty pair A] ⇄ relay ⇄ [pty pair B] ⇄ pymodbus slave (subprocess)
                                      │
                                      └─ every byte, as it passes, with its read time

Pseudo-terminals on this kernel refuse even and odd parity and ignore the baud rate,
so the lines run 8N1 and the times are host read times.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import serial

from decoders.crc import crc_ok

SOCAT = shutil.which("socat")

SLAVE_SCRIPT = """
import sys
from pymodbus import FramerType, ModbusDeviceIdentification
from pymodbus.datastore import ModbusDeviceContext, ModbusSequentialDataBlock, ModbusServerContext
from pymodbus.server import StartSerialServer

def device():
    return ModbusDeviceContext(
        co=ModbusSequentialDataBlock(1, [i % 3 == 0 for i in range(100)]),
        di=ModbusSequentialDataBlock(1, [i % 2 == 0 for i in range(100)]),
        hr=ModbusSequentialDataBlock(1, list(range(100, 200))),
        ir=ModbusSequentialDataBlock(1, list(range(1000, 1100))),
    )

context = ModbusServerContext(devices={1: device(), 17: device()}, single=False)
identity = ModbusDeviceIdentification(
    info_name={"VendorName": "rtusniff tests", "ProductCode": "PTY-1", "MajorMinorRevision": "1.0"}
)
StartSerialServer(context=context, identity=identity, framer=FramerType.RTU, port=sys.argv[1],
                  baudrate=19200, parity="N", timeout=1)
"""


@dataclass
class PtyPair:
    """Two connected pseudo-terminals, as symlinks ``a`` and ``b``."""

    a: Path
    b: Path
    process: subprocess.Popen[bytes]


@contextmanager
def pty_pair(directory: Path, name: str) -> Iterator[PtyPair]:
    if SOCAT is None:
        raise RuntimeError("socat is not installed")
    a, b = directory / f"{name}-a", directory / f"{name}-b"
    process = subprocess.Popen(
        [SOCAT, f"PTY,raw,echo=0,link={a}", f"PTY,raw,echo=0,link={b}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 5
        while not (a.exists() and b.exists()):
            if time.monotonic() > deadline:
                raise RuntimeError("socat did not create its pseudo-terminals")
            time.sleep(0.01)
        yield PtyPair(a, b, process)
    finally:
        process.terminate()
        process.wait(timeout=5)


@dataclass
class Relay:
    """Copies bytes between two ports and keeps a copy of each read with its time.

    Requests from the master side whose address is in ``absent`` are recorded but not passed
    on: a drive missing from the bus. A request may come in several reads (a loaded machine
    splits them), so the address is its first read's first byte, and a request lasts until its
    bytes end in their CRC (or 0.1 s of quiet): ``01 03 00 00 00 04 44`` then ``09`` once lost
    its last byte to ``absent={9}``, and its slave never answered.
    """

    master_side: Path
    slave_side: Path
    absent: frozenset[int] = frozenset()
    #: A third port that gets a copy of every byte, as a passive tap on the line would.
    copy_to: Path | None = None
    tap: list[tuple[int, bytes]] = field(default_factory=list)
    _stop: threading.Event = field(default_factory=threading.Event)
    _thread: threading.Thread | None = None
    #: The master's request being relayed (its bytes so far), when its last read came, and whether
    #: it is for an absent slave.
    _request: bytearray = field(default_factory=bytearray)
    _request_ns: int = 0
    _dropping: bool = False

    def __enter__(self) -> Relay:
        self._ports = [serial.Serial(str(p), 19200, timeout=0) for p in (self.master_side, self.slave_side)]
        self._copy = serial.Serial(str(self.copy_to), 19200, timeout=0) if self.copy_to else None
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        assert self._thread is not None
        self._thread.join(timeout=5)
        for port in self._ports:
            port.close()
        if self._copy is not None:
            self._copy.close()

    def written_back(self) -> bytes:
        """Whatever arrived from the tap's side: a passive tap sends nothing."""
        assert self._copy is not None
        return bytes(self._copy.read(4096))

    def _run(self) -> None:
        fds = {port.fileno(): (port, other) for port, other in zip(self._ports, reversed(self._ports), strict=True)}
        while not self._stop.is_set():
            ready, _, _ = select.select(list(fds), [], [], 0.05)
            for fd in ready:
                port, other = fds[fd]
                data = os.read(fd, 4096)
                if data:
                    self.tap.append((time.time_ns(), data))
                    if self._copy is not None:
                        self._copy.write(data)
                    if not (port is self._ports[0] and self._absent(data)):
                        other.write(data)

    def _absent(self, data: bytes) -> bool:
        """Whether ``data``, read from the master's side, belongs to a request for an absent slave."""
        now = time.monotonic_ns()
        if not self._request or now - self._request_ns > 100_000_000:  # a request starts
            self._request.clear()
            self._dropping = data[0] in self.absent
        self._request += data
        self._request_ns = now
        if len(self._request) >= 4 and crc_ok(bytes(self._request)):
            self._request.clear()
        return self._dropping


@contextmanager
def pymodbus_slave(port: Path) -> Iterator[subprocess.Popen[bytes]]:
    process = subprocess.Popen([sys.executable, "-c", SLAVE_SCRIPT, str(port)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        time.sleep(1.0)  # the server opens its port
        if process.poll() is not None:
            raise RuntimeError(f"pymodbus slave died: {process.stderr.read().decode() if process.stderr else ''}")
        yield process
    finally:
        process.terminate()
        process.wait(timeout=5)


def write_text_capture(path: Path, tap: list[tuple[int, bytes]], note: str) -> None:
    lines = ["# rtu-capture v1", "# line: 19200 8N1", "# timing: host", f"# {note}"]
    lines += [f"{t // 1_000_000_000}.{t % 1_000_000_000:09d} {data.hex(' ').upper()}" for t, data in tap]
    path.write_text("\n".join(lines) + "\n")
