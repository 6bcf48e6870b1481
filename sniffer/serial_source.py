"""A passive serial tap: reads a port, never writes to it.

Some RS485 adapters switch their driver on with RTS (or DTR): both are set off
*before* the port is opened, so that opening it never drives the line. Reads are
stamped with a monotonic clock mapped once to wall time, in nanoseconds, when the
read returns: ``host`` timing.

What the driver offers is reported, not required: low-latency mode
(ASYNC_LOW_LATENCY), the FTDI latency timer (sysfs), and the UART error counters
(TIOCGICOUNT: framing, parity, overrun).

Runs on Linux, macOS and Windows: the POSIX-only modules (``fcntl``, ``termios``) are
imported where they are used, and where they are missing the port is read through
pyserial's own ``read`` and the error counters are simply not offered.
"""

from __future__ import annotations

import errno
import importlib
import os
import re
import select
import struct
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from decoders.capture import Chunk
from decoders.line import LineSettings, Parity
from sniffer.errors import ErrorKind, RtuSniffError

READ_SIZE = 65536
#: Linux TIOCGICOUNT: struct serial_icounter_struct (cts dsr rng dcd rx tx frame overrun parity brk buf_overrun).
TIOCGICOUNT_LINUX = 0x545D
_ICOUNT = struct.Struct("11i9i")
ICOUNT_FIELDS = ("cts", "dsr", "rng", "dcd", "rx", "tx", "frame", "overrun", "parity", "brk", "buf_overrun")
SLOW_LATENCY_TIMER_MS = 4

#: pyserial's parity names (``serial.PARITY_*``), which are these letters.
_PARITY = {Parity.NONE: "N", Parity.EVEN: "E", Parity.ODD: "O", Parity.MARK: "M", Parity.SPACE: "S"}


def pyserial() -> ModuleType:
    """pyserial, imported when a port is used: it imports ``fcntl`` and ``termios`` on POSIX,
    and commands that read files (analyze, stats, export) need none of it."""
    return importlib.import_module("serial")


def posix_module(name: str) -> ModuleType | None:
    """``fcntl`` or ``termios`` where the platform has them (not on Windows), else ``None``."""
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def port_errors() -> tuple[type[BaseException], ...]:
    """What opening or configuring a port raises when the port refuses: pyserial's error, an
    OS error, a bad value, and on POSIX ``termios.error`` (a setting the driver rejects)."""
    termios = posix_module("termios")
    extra: tuple[type[BaseException], ...] = (termios.error,) if termios is not None else ()
    return (pyserial().SerialException, OSError, ValueError, *extra)


class PortGoneError(Exception):
    """The port vanished (adapter unplugged, pty closed)."""


@dataclass(frozen=True)
class PortStatus:
    """What the driver let us do and know; ``None`` where it offers nothing."""

    low_latency: bool | None
    latency_timer_ms: int | None
    counters_available: bool
    #: RTS and DTR as the driver reports them after they were cleared; ``None``: it cannot say
    #: (a pseudo-terminal has no modem lines; Windows).
    modem_lines: dict[str, bool] | None = None
    #: A port whose reads return as bytes arrive (a board's own UART, a pseudo-terminal): no
    #: USB adapter holds them back.
    prompt: bool = False

    @property
    def delivery_ms(self) -> int | None:
        """How late, at most, reads deliver bytes (an FTDI adapter's latency timer; 0 on a prompt
        port); ``None``: not known (another USB adapter, Windows, macOS)."""
        if self.latency_timer_ms is not None:
            return self.latency_timer_ms
        return 0 if self.prompt else None

    def modem_note(self) -> str:
        """What is known of RTS and DTR, for the recording's notes and the warnings."""
        if self.modem_lines is None:
            return "RTS/DTR: cleared; this port cannot report them back (no modem lines, or not POSIX)"
        raised = [name for name, on in self.modem_lines.items() if on]
        if raised:
            return (f"RTS/DTR: {' and '.join(raised)} still on after clearing: an adapter that enables its "
                    "transmitter with it would drive the line")
        return "RTS/DTR: both off, as the driver reports them"

    def advice(self) -> str | None:
        if self.latency_timer_ms is not None and self.latency_timer_ms > SLOW_LATENCY_TIMER_MS:
            return (f"the adapter's latency timer is {self.latency_timer_ms} ms: bytes reach the PC in bursts; "
                    "for better times: echo 1 | sudo tee /sys/bus/usb-serial/devices/<tty>/latency_timer")
        return None


class SerialSource:
    """One port, opened passively; :meth:`read` returns timestamped chunks."""

    def __init__(self, port: str, line: LineSettings) -> None:
        self.port = port
        self.line = line
        serial = pyserial()
        self._serial = serial.Serial()
        self._serial.port = port
        self._serial.baudrate = line.baud
        self._serial.bytesize = line.data_bits
        self._serial.parity = _PARITY[line.parity]
        self._serial.stopbits = serial.STOPBITS_TWO if line.stop_bits == 2 else serial.STOPBITS_ONE
        self._serial.timeout = 0
        # Off before opening: an RS485 adapter that keys its driver on RTS/DTR stays silent.
        self._serial.rts = False
        self._serial.dtr = False
        if os.name == "posix":
            # An advisory lock (flock) other captures take too: two captures on one port would each
            # get part of the bytes. Windows opens a port for one program only anyway.
            self._serial.exclusive = True
        self._offset_ns = time.time_ns() - time.monotonic_ns()
        #: Set when a read has bytes to return (stamped no earlier), cleared by :meth:`delivered`.
        self._in_flight_ns: int | None = None

    def open(self) -> PortStatus:
        try:
            self._serial.open()
        except port_errors() as exc:
            if "exclusively lock" in str(exc):
                raise RtuSniffError(ErrorKind.FILE_UNREADABLE, "the port is in use: another capture (or a program "
                                    "that locks it) reads it; two readers would each get only part of the "
                                    "bytes", path=self.port) from None
            raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot open the port with {self.line.format()}: "
                                f"{exc}", path=self.port) from None
        self._clear_modem_lines()
        return PortStatus(self._low_latency(), _latency_timer_ms(self.port), self.counters() is not None,
                          self.modem_lines(), prompt=_is_prompt(self.port))

    def _clear_modem_lines(self) -> None:
        """RTS and DTR off again, each on its own: pyserial clears them at open in one step that
        skips RTS when clearing DTR fails (it does on a pseudo-terminal)."""
        for name in ("dtr", "rts"):
            try:
                setattr(self._serial, name, False)
            except port_errors():
                continue

    def modem_lines(self) -> dict[str, bool] | None:
        """RTS and DTR as the driver has them (TIOCMGET); ``None`` where it cannot say."""
        fcntl, termios = posix_module("fcntl"), posix_module("termios")
        if fcntl is None or termios is None or not hasattr(termios, "TIOCMGET"):
            return None
        try:
            raw = fcntl.ioctl(self._serial.fileno(), termios.TIOCMGET, struct.pack("I", 0))
        except (OSError, ValueError):
            return None
        bits = struct.unpack("I", raw)[0]
        return {"RTS": bool(bits & termios.TIOCM_RTS), "DTR": bool(bits & termios.TIOCM_DTR)}

    @property
    def rts(self) -> bool:
        return bool(self._serial.rts)

    @property
    def dtr(self) -> bool:
        return bool(self._serial.dtr)

    def _low_latency(self) -> bool | None:
        try:
            self._serial.set_low_latency_mode(True)
        except (OSError, ValueError, AttributeError):
            return None
        return True

    def counters(self) -> dict[str, int] | None:
        """The UART's error counters, where the driver has them."""
        fcntl, termios = posix_module("fcntl"), posix_module("termios")
        if fcntl is None or termios is None:
            return None
        try:
            request = getattr(termios, "TIOCGICOUNT", TIOCGICOUNT_LINUX)
            raw = fcntl.ioctl(self._serial.fileno(), request, bytes(_ICOUNT.size))
        except (OSError, AttributeError, ValueError):
            return None
        return dict(zip(ICOUNT_FIELDS, _ICOUNT.unpack(raw)[:11], strict=True))

    def read(self, timeout_s: float) -> Chunk | None:
        """The bytes that arrived, stamped when the read returned; ``None`` after ``timeout_s``."""
        if os.name != "posix":
            return self._read_portable(timeout_s)
        fd = self._serial.fileno()
        try:
            ready, _, _ = select.select([fd], [], [], timeout_s)
            if not ready:
                return None
            self._in_flight_ns = self.now_ns()
            data = os.read(fd, READ_SIZE)
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.ENXIO, errno.ENODEV, errno.EBADF):
                raise PortGoneError(f"{exc.strerror}") from None
            raise
        stamp = time.monotonic_ns() + self._offset_ns
        if not data:
            raise PortGoneError("end of file")
        return Chunk(stamp, data)

    def _read_portable(self, timeout_s: float) -> Chunk | None:
        """:meth:`read` through pyserial (Windows: ``select`` takes only sockets there)."""
        try:
            self._serial.timeout = timeout_s
            data = self._serial.read(1)
            if data:
                self._in_flight_ns = self.now_ns()
                data += self._serial.read(self._serial.in_waiting)
        except (pyserial().SerialException, OSError) as exc:
            raise PortGoneError(str(exc)) from None
        if not data:
            return None
        return Chunk(time.monotonic_ns() + self._offset_ns, data)

    def now_ns(self) -> int:
        """The same clock the chunks are stamped with."""
        return time.monotonic_ns() + self._offset_ns

    def delivered(self) -> None:
        """The chunk :meth:`read` returned is where its consumer finds it (queued for decoding)."""
        self._in_flight_ns = None

    def heard_until_ns(self) -> int:
        """A time before which every read is delivered: now, or where a read not yet delivered
        began. A reader stamps a read when it returns and queues it a little later, much later on
        a loaded machine: a decoder whose clock ran past such a read would time out a request
        whose answer was read in time and waits to be queued. Read this before taking what
        was delivered (one that begins after it is stamped later)."""
        now = self.now_ns()
        in_flight = self._in_flight_ns
        return now if in_flight is None else min(now, in_flight)

    def close(self) -> None:
        self._serial.close()


def _latency_timer_ms(port: str) -> int | None:
    name = Path(os.path.realpath(port)).name
    timer = Path("/sys/bus/usb-serial/devices") / name / "latency_timer"
    try:
        return int(timer.read_text().strip())
    except (OSError, ValueError):
        return None


#: Linux names of ports that are no USB adapter: board UARTs (8250, PL011, i.MX, Samsung) and
#: pseudo-terminals.
_PROMPT_PORTS = re.compile(r"/dev/(ttyS|ttyAMA|ttymxc|ttySAC|pts/)\d+")


def _is_prompt(port: str) -> bool:
    return sys.platform.startswith("linux") and _PROMPT_PORTS.fullmatch(os.path.realpath(port)) is not None


def serial_ports() -> list[tuple[str, str, str]]:
    """(device, description, hardware id) of every serial port pyserial finds."""
    list_ports = importlib.import_module("serial.tools.list_ports")
    return [(p.device, p.description, p.hwid) for p in sorted(list_ports.comports(), key=lambda p: p.device)]
