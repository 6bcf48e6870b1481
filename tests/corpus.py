"""Captures with known ground truth, for the framer's tests and quality figures.

Frames come from pymodbus (its PDU classes and RTU framer), an implementation
independent of ours. A :class:`Scenario` turns a random polling conversation into
wire transmissions with one of the faults real lines show; :func:`usb_adapter`
turns an exact capture into the host-timed one a USB-RS485 adapter would give.
Every byte is labelled: which frame (or noise) it belongs to, and what the framer
should say about it.
"""

from __future__ import annotations

import functools
import random
from collections.abc import Callable
from dataclasses import dataclass, field

from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU, ModbusPDU
from pymodbus.pdu import bit_message as bits
from pymodbus.pdu import diag_message as diag
from pymodbus.pdu import mei_message as mei
from pymodbus.pdu import register_message as regs
from pymodbus.pdu.exceptionresponse import ExceptionResponse

from benchmarks.read_loops import READ_LOOPS
from benchmarks.wire_synthesis import Transmission, exact_chunks, usb_adapter_chunks
from decoders.capture import Chunk, TimingQuality
from decoders.line import LineSettings

T0_NS = 1_650_000_000_000_000_000
MS = 1_000_000
_FRAMER = FramerRTU(DecodePDU(False))


def adu(pdu: ModbusPDU) -> bytes:
    """The RTU frame pymodbus builds for ``pdu``."""
    return bytes(_FRAMER.buildFrame(pdu))


def _words(rng: random.Random, count: int) -> list[int]:
    return [rng.randrange(65536) for _ in range(count)]


def _bools(rng: random.Random, count: int) -> list[bool]:
    return [rng.random() < 0.5 for _ in range(count)]


#: The request and response classes of FC 3 and FC 4.
_REGISTER_READS: dict[int, tuple[type[ModbusPDU], type[ModbusPDU]]] = {
    3: (regs.ReadHoldingRegistersRequest, regs.ReadHoldingRegistersResponse),
    4: (regs.ReadInputRegistersRequest, regs.ReadInputRegistersResponse),
}


def exchange(rng: random.Random, slave: int) -> tuple[bytes, bytes]:
    """A request and its response (sometimes an exception), both from pymodbus."""
    kind = rng.choice(["fc1", "fc2", "fc3", "fc4", "fc5", "fc6", "fc8", "fc15", "fc16", "fc22", "fc23", "fc43", "exc"])
    address = rng.randrange(0, 60000)
    count = rng.randint(1, 40)
    if kind in ("fc1", "fc2"):
        cls_req, cls_resp = (
            (bits.ReadCoilsRequest, bits.ReadCoilsResponse)
            if kind == "fc1"
            else (bits.ReadDiscreteInputsRequest, bits.ReadDiscreteInputsResponse)
        )
        return adu(cls_req(dev_id=slave, address=address, count=count)), adu(
            cls_resp(dev_id=slave, bits=_bools(rng, count))
        )
    if kind in ("fc3", "fc4"):
        cls_req, cls_resp = _REGISTER_READS[int(kind[2:])]
        return adu(cls_req(dev_id=slave, address=address, count=count)), adu(
            cls_resp(dev_id=slave, registers=_words(rng, count))
        )
    if kind == "fc5":
        frame = adu(bits.WriteSingleCoilRequest(dev_id=slave, address=address, bits=[rng.random() < 0.5]))
        return frame, frame
    if kind == "fc6":
        frame = adu(regs.WriteSingleRegisterRequest(dev_id=slave, address=address, registers=_words(rng, 1)))
        return frame, frame
    if kind == "fc8":
        frame = adu(diag.ReturnQueryDataRequest(dev_id=slave, message=rng.randrange(65536)))
        return frame, frame
    if kind == "fc15":
        values = _bools(rng, count)
        return adu(bits.WriteMultipleCoilsRequest(dev_id=slave, address=address, bits=values)), adu(
            bits.WriteMultipleCoilsResponse(dev_id=slave, address=address, count=count)
        )
    if kind == "fc16":
        values = _words(rng, min(count, 30))
        return adu(regs.WriteMultipleRegistersRequest(dev_id=slave, address=address, registers=values)), adu(
            regs.WriteMultipleRegistersResponse(dev_id=slave, address=address, count=len(values))
        )
    if kind == "fc22":
        frame = adu(regs.MaskWriteRegisterRequest(dev_id=slave, address=address, and_mask=0xF0F0, or_mask=0x0101))
        return frame, frame
    if kind == "fc23":
        reads, writes = rng.randint(1, 20), _words(rng, rng.randint(1, 20))
        request = regs.ReadWriteMultipleRegistersRequest(
            dev_id=slave, read_address=address, read_count=reads, write_address=address + 100, write_registers=writes
        )
        return adu(request), adu(regs.ReadWriteMultipleRegistersResponse(dev_id=slave, registers=_words(rng, reads)))
    if kind == "fc43":
        info = {0: b"Schneider Electric", 1: b"ATV71HU15M3", 2: b"0201"}
        return adu(mei.ReadDeviceInformationRequest(dev_id=slave, read_code=1, object_id=0)), adu(
            mei.ReadDeviceInformationResponse(dev_id=slave, read_code=1, information=info)
        )
    function = rng.choice([3, 6, 16])
    request = adu(regs.ReadHoldingRegistersRequest(dev_id=slave, address=address, count=count)) if function == 3 else (
        adu(regs.WriteSingleRegisterRequest(dev_id=slave, address=address, registers=_words(rng, 1)))
    )
    if function == 16:
        request = adu(regs.WriteMultipleRegistersRequest(dev_id=slave, address=address, registers=_words(rng, 3)))
    return request, adu(ExceptionResponse(function, rng.choice([1, 2, 3, 4, 6]), device_id=slave))


def read_ending_in_zero(rng: random.Random, slave: int) -> tuple[bytes, bytes] | None:
    """An FC 3/4 read of one register at 0x02xx whose CRC ends in 0x00, and its answer: the
    request reads as a 7-byte answer and a 0x00 glitch too (``None`` if ``slave`` has none)."""
    found = _request_ending_in_zero(slave)
    if found is None:
        return None
    function, request = found
    return request, adu(_REGISTER_READS[function][1](dev_id=slave, registers=_words(rng, 1)))


@functools.cache
def _request_ending_in_zero(slave: int) -> tuple[int, bytes] | None:
    """The function and bytes of :func:`read_ending_in_zero`'s request: searched once a slave
    (up to 512 frames built)."""
    for function, address in ((f, 0x0200 + low) for f in (3, 4) for low in range(256)):
        request = adu(_REGISTER_READS[function][0](dev_id=slave, address=address, count=1))
        if request.endswith(b"\x00"):
            return function, request
    return None


@dataclass(frozen=True)
class Expected:
    """What the framer should report for one transmission."""

    data: bytes
    is_noise: bool = False
    crc_ok: bool = True
    flags: frozenset[str] = frozenset()
    #: "request" or "response" (an answer: response or exception) for frames sent as such.
    role: str = ""


@dataclass
class Corpus:
    """A capture with its ground truth, in wire order."""

    name: str
    line: LineSettings
    timing: TimingQuality
    chunks: list[Chunk]
    expected: list[Expected]
    transmissions: list[Transmission] = field(repr=False, default_factory=list)


@dataclass(frozen=True)
class Scenario:
    """One of the conditions of real lines, applied to a polling conversation."""

    name: str
    #: Silence before a response, as a fraction of t3.5 (below 1: a too-fast slave).
    turnaround: tuple[float, float] = (1.5, 6.0)
    #: Silence before a request, as a fraction of t3.5.
    poll_gap: tuple[float, float] = (1.2, 8.0)
    #: Silence before every frame in character times instead (a bus that never leaves t3.5).
    idle_chars: tuple[float, float] | None = None
    gap_1_5_rate: float = 0.0
    #: A stray byte directly after a response (and after a request with ``glitch_after_requests``).
    glitch_rate: float = 0.0
    glitch_values: tuple[int, ...] = (0x00, 0xFF)
    glitch_after_requests: bool = False
    #: 0x00 after a master's frame, 0xFE after a slave's, any value one time in ten.
    glitch_by_side: bool = False
    #: Stray bytes on both sides of a frame, no silence between them and the frame.
    junk_around_rate: float = 0.0
    garbage_rate: float = 0.0
    corrupt_rate: float = 0.0
    #: A response cut off (the slave stopped sending), the next request after a silence.
    truncate_rate: float = 0.0
    #: FC 8 sub-function 0 requests echoing 1-120 bytes.
    echo_rate: float = 0.0
    slaves: tuple[int, int] = (1, 32)
    #: A request left unanswered (the slave silent), then sent again after the master's
    #: timeout, once or twice, before its answer.
    retry_rate: float = 0.0
    #: A request replaced by a read ending in 0x00 (:func:`read_ending_in_zero`).
    zero_ending_rate: float = 0.0
    start_mid_frame: bool = False
    truncate_end: bool = False


SCENARIOS = [
    Scenario("clean", gap_1_5_rate=0.05),
    # The nine classes real wires and read loops showed (issue 16); 2, 7 and 8 are read
    # loops (benchmarks/read_loops.py: read-timeout, random-sizes, slow-delivery) over these.
    Scenario("glitch-polling", idle_chars=(1.6, 3.0), glitch_rate=1.0, glitch_after_requests=True,
             glitch_by_side=True),
    Scenario("junk-both-sides", junk_around_rate=0.5),
    Scenario("high-address", slaves=(240, 255), idle_chars=(1.6, 3.0), glitch_rate=0.3, glitch_by_side=True),
    Scenario("zero-after-frame", slaves=(1, 255), glitch_rate=1.0, glitch_values=(0x00,), glitch_after_requests=True),
    Scenario("echo-fc8", echo_rate=0.5),
    Scenario("broken-answers", truncate_rate=0.1, corrupt_rate=0.05),
    Scenario("fast-slave", turnaround=(0.0, 0.95)),
    Scenario("turn-off-glitch", glitch_rate=0.5),
    Scenario("garbage", garbage_rate=0.1, start_mid_frame=True),
    Scenario("bit-errors", corrupt_rate=0.05),
    Scenario("truncated", truncate_end=True),
    # A master's retries, half of them of requests that read as an answer and a glitch too.
    Scenario("retries", retry_rate=0.3, zero_ending_rate=0.5),
    Scenario("everything", turnaround=(0.3, 4.0), gap_1_5_rate=0.03, glitch_rate=0.2, garbage_rate=0.03,
             corrupt_rate=0.03, start_mid_frame=True, truncate_end=True),
]
LINES = [LineSettings.parse(t) for t in ("9600 8N1", "19200 8E1", "115200 8N1")]


def build(scenario: Scenario, line: LineSettings, exchanges: int = 300, seed: int = 0) -> Corpus:
    """An exact capture of ``exchanges`` request/response pairs under ``scenario``."""
    rng = random.Random(f"{scenario.name}/{line.format()}/{seed}")
    t3_5 = line.t3_5_ns
    t1_5 = line.t1_5_ns
    out: list[tuple[Transmission, Expected]] = []

    def idle(low: float, high: float) -> int:
        if scenario.idle_chars is not None:
            return int(rng.uniform(*scenario.idle_chars) * line.char_time_ns) + 2
        return int(rng.uniform(low, high) * t3_5) + 2

    def send(data: bytes, silence: int, expected: Expected) -> None:
        gaps: dict[int, int] = {}
        if not expected.is_noise and len(data) > 2 and rng.random() < scenario.gap_1_5_rate:
            gaps[rng.randrange(1, len(data))] = int(rng.uniform(t1_5 * 1.1, t3_5 * 0.9))
            expected = Expected(expected.data, expected.is_noise, expected.crc_ok, expected.flags | {"gap_1_5"},
                                expected.role)
        if not expected.is_noise and silence < t3_5 and out:  # the capture's first frame has no silence before it
            expected = Expected(expected.data, expected.is_noise, expected.crc_ok, expected.flags | {"short_idle"},
                                expected.role)
        out.append((Transmission(data, silence, gaps), expected))

    def noise(data: bytes, silence: int) -> None:
        send(data, silence, Expected(data, is_noise=True, crc_ok=False))

    def glitch(after_request: bool) -> None:
        if scenario.glitch_by_side:
            value = rng.randrange(256) if rng.random() < 0.1 else (0x00 if after_request else 0xFE)
        else:
            value = rng.choice(scenario.glitch_values)
        noise(bytes([value]), int(rng.uniform(0, 0.9) * line.char_time_ns))

    def frame(data: bytes, silence: int, expected: Expected, *, after_request: bool) -> None:
        junk = rng.random() < scenario.junk_around_rate
        if junk:
            noise(rng.randbytes(rng.randint(1, 3)), silence)
            silence = 0
        send(data, silence, expected)
        if junk:
            noise(rng.randbytes(1), 0)
        elif (scenario.glitch_after_requests or not after_request) and rng.random() < scenario.glitch_rate:
            glitch(after_request)

    if scenario.start_mid_frame:
        request, _ = exchange(rng, 1)
        noise(request[3:], 0)
    for _ in range(exchanges):
        slave = rng.randint(*scenario.slaves)
        request, response = exchange(rng, slave)
        if rng.random() < scenario.echo_rate:
            request = adu(diag.ReturnQueryDataRequest(dev_id=slave, message=rng.randbytes(rng.randint(1, 120))))
            response = request
        # Rates of 0 draw nothing: the other scenarios' conversations stay as they were.
        zero_ending = read_ending_in_zero(rng, slave) if scenario.zero_ending_rate and \
            rng.random() < scenario.zero_ending_rate else None
        if zero_ending is not None:
            request, response = zero_ending
        frame(request, idle(*scenario.poll_gap), Expected(request, role="request"), after_request=True)
        if scenario.retry_rate and rng.random() < scenario.retry_rate:
            for _ in range(rng.randint(1, 2)):  # unanswered: sent again once the master timed out
                frame(request, idle(10.0, 40.0), Expected(request, role="request"), after_request=True)
        expected = Expected(response, role="response")
        if len(response) > 6 and rng.random() < scenario.corrupt_rate:
            # A bit error in the data: address, function, byte count and CRC stay readable.
            position = rng.randrange(3, len(response) - 2)
            damaged = bytearray(response)
            damaged[position] ^= 1 << rng.randrange(8)
            response = bytes(damaged)
            expected = Expected(response, crc_ok=False, role="response")
        elif len(response) > 5 and rng.random() < scenario.truncate_rate:
            response = response[: rng.randint(4, len(response) - 1)]
            expected = Expected(response, crc_ok=False, flags=frozenset({"truncated"}), role="response")
        frame(response, idle(*scenario.turnaround), expected, after_request=False)
        if rng.random() < scenario.garbage_rate:
            junk = bytes([0xFF]) + rng.randbytes(rng.randint(1, 12))  # 0xFF: no slave has that address
            noise(junk, idle(1.2, 3.0))
    if scenario.truncate_end:
        request, _ = exchange(rng, 7)
        cut = request[: rng.randint(4, len(request) - 1)]
        send(cut, idle(1.2, 3.0), Expected(cut, crc_ok=False, flags=frozenset({"truncated"})))
    transmissions = [t for t, _ in out]
    return Corpus(
        name=scenario.name,
        line=line,
        timing=TimingQuality.EXACT,
        chunks=list(exact_chunks(transmissions, line, T0_NS)),
        expected=_joined_noise([e for _, e in out], [t.idle_before_ns > t1_5 for t in transmissions]),
        transmissions=transmissions,
    )


def _joined_noise(expected: list[Expected], pause_before: list[bool]) -> list[Expected]:
    """Noise transmissions with no pause between them are one noise record on the wire."""
    joined: list[Expected] = []
    for item, pause in zip(expected, pause_before, strict=True):
        if joined and item.is_noise and joined[-1].is_noise and not pause:
            joined[-1] = Expected(joined[-1].data + item.data, is_noise=True, crc_ok=False)
        else:
            joined.append(item)
    return joined


def usb_adapter(corpus: Corpus, latency_ms: float = 16.0, seed: int = 0) -> Corpus:
    """The corpus as a host reading a USB-serial adapter records it (62-byte buffer)."""
    chunks = usb_adapter_chunks(corpus.chunks, corpus.line, latency_ns=int(latency_ms * MS), seed=seed)
    return Corpus(corpus.name + "/host", corpus.line, TimingQuality.HOST, chunks, corpus.expected, corpus.transmissions)


def host_expected(expected: list[Expected]) -> list[Expected]:
    """Host timing cannot see silences: no gap_1_5 or short_idle is expected, and noise
    runs next to each other are one."""
    plain = [Expected(e.data, e.is_noise, e.crc_ok, e.flags - {"gap_1_5", "short_idle"}, e.role) for e in expected]
    return _joined_noise(plain, [False] * len(plain))


def deliver(corpus: Corpus, read_loop: str, seed: int = 0) -> Corpus:
    """The corpus as the named read loop (benchmarks/read_loops.py) records it."""
    chunks = READ_LOOPS[read_loop](corpus.chunks, corpus.line, seed)
    return Corpus(f"{corpus.name}/{read_loop}", corpus.line, TimingQuality.HOST, chunks, corpus.expected,
                  corpus.transmissions)


Builder = Callable[[Scenario, LineSettings], Corpus]


@dataclass
class Score:
    """How the framer's pieces compare with the ground truth, by byte position."""

    frames: int = 0
    frames_found: int = 0
    pieces: int = 0
    pieces_exact: int = 0
    emitted_frames: int = 0
    spurious_valid: int = 0
    false_flags: dict[str, int] = field(default_factory=dict)
    missed_flags: dict[str, int] = field(default_factory=dict)

    @property
    def recall(self) -> float:
        return self.frames_found / self.frames if self.frames else 1.0

    @property
    def precision(self) -> float:
        valid_emitted = self.emitted_frames
        return self.frames_found / valid_emitted if valid_emitted else 1.0

    def add(self, other: Score) -> None:
        for name in ("frames", "frames_found", "pieces", "pieces_exact", "emitted_frames", "spurious_valid"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        for mine, theirs in ((self.false_flags, other.false_flags), (self.missed_flags, other.missed_flags)):
            for flag, count in theirs.items():
                mine[flag] = mine.get(flag, 0) + count


FLAGS_SCORED = ("gap_1_5", "short_idle", "truncated")


def score(expected: list[Expected], emitted: list[tuple[bytes, bool, bool, frozenset[str]]]) -> Score:
    """Compare emitted (data, is_noise, crc_ok, flags) pieces with the ground truth."""
    truth: dict[tuple[int, int], Expected] = {}
    offset = 0
    for item in expected:
        truth[(offset, len(item.data))] = item
        offset += len(item.data)
    result = Score()
    result.frames = sum(1 for e in expected if not e.is_noise and e.crc_ok)
    result.pieces = len(expected)
    offset = 0
    for data, is_noise, crc_ok, flags in emitted:
        item = truth.get((offset, len(data)))
        offset += len(data)
        if not is_noise and crc_ok:
            result.emitted_frames += 1
            if item is None or item.is_noise or not item.crc_ok:
                result.spurious_valid += 1
            else:
                result.frames_found += 1
        if item is None:
            continue
        if (item.is_noise, item.crc_ok) == (is_noise, crc_ok):
            result.pieces_exact += 1
        for flag in FLAGS_SCORED:
            if flag in flags and flag not in item.flags:
                result.false_flags[flag] = result.false_flags.get(flag, 0) + 1
            if flag in item.flags and flag not in flags:
                result.missed_flags[flag] = result.missed_flags.get(flag, 0) + 1
    return result
