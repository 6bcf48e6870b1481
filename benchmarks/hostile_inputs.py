"""Hostile inputs, shared by the reliability benchmark, the tests and the fuzz targets: crafted
MCAP captures, text captures of hostile sizes and times, and hostile profiles.

Each was found to break rtusniff once (a traceback, gigabytes, minutes); each must now be one
error line with a documented exit code, in little memory and time.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.io import mcap_blocks
from sniffer.io.registry import open_writer

T0 = 1_700_000_000_000_000_000
LINE = LineSettings.parse("19200 8E1")
FIELDS = {"format_version": "1", "timing": "exact", "line": "19200 8E1", "notes": "[]"}


def crafted_mcap(path: Path, fields: dict[str, str], blocks: list[ChunkBatch], late_notes: str | None = None) -> Path:
    """An MCAP written with the standard writer: rtusniff's metadata as given, the blocks, and a
    late notes record."""
    from mcap.writer import Writer

    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="rtusniff", library="hostile")
        writer.add_metadata(mcap_blocks.METADATA_NAME, fields)
        channel = writer.register_channel(topic=mcap_blocks.TOPIC, message_encoding=mcap_blocks.MESSAGE_ENCODING,
                                          schema_id=0)
        for block in blocks:
            t = max(int(block.t_end_ns[0]), 0)
            writer.add_message(channel_id=channel, log_time=t, publish_time=t, data=mcap_blocks.encode_block(block))
        if late_notes is not None:
            writer.add_metadata(mcap_blocks.NOTES_METADATA_NAME, {"notes": late_notes})
        writer.finish()
    return path


def block_at(*times: int, data: bytes = b"\x01\x03") -> ChunkBatch:
    return ChunkBatch.from_chunks([Chunk(t, data) for t in times])


def first_chunk_offset(data: bytes) -> int:
    """Where the first MCAP Chunk record (opcode 0x06) starts, walking the records after the magic."""
    position = 8
    while data[position] != 0x06:
        position += 9 + int.from_bytes(data[position + 1 : position + 9], "little")
    return position


def chunk_bomb(path: Path, claimed: int = 7 * 2**30) -> Path:
    """A small MCAP whose first chunk claims ``claimed`` bytes uncompressed."""
    crafted_mcap(path, FIELDS, [block_at(T0, T0 + 1_000_000)])
    data = bytearray(path.read_bytes())
    at = first_chunk_offset(data) + 9 + 16  # opcode, length, start and end times
    data[at : at + 8] = claimed.to_bytes(8, "little")
    path.write_bytes(bytes(data))
    return path


def _chunk_record(compression: str, data: bytes, claimed: int) -> bytes:
    """An MCAP Chunk record (opcode 0x06) holding ``data`` compressed as ``compression``."""
    import struct

    name = compression.encode()
    body = (struct.pack("<QQQI", T0, T0, claimed, 0) + struct.pack("<I", len(name)) + name
            + struct.pack("<Q", len(data)) + data)
    return b"\x06" + struct.pack("<Q", len(body)) + body


def inflate_bomb(path: Path, compression: str, inflated_mib: int = 256, claimed: int = 100) -> Path:
    """A small MCAP whose first chunk declares ``claimed`` bytes but holds a ``compression``
    frame of ``inflated_mib`` MiB (a zstd frame that says so in its header; lz4 says nothing)."""
    piece = bytes(2**20)
    if compression.startswith("zstd"):  # "zstd-unsized": a frame that does not say its size
        import zstandard

        sized = compression == "zstd"
        compressor = zstandard.ZstdCompressor(write_content_size=sized).compressobj(
            size=inflated_mib * 2**20 if sized else -1)
        data = b"".join(compressor.compress(piece) for _ in range(inflated_mib)) + compressor.flush()
    else:
        import lz4.frame  # type: ignore[import-untyped]

        compressor = lz4.frame.LZ4FrameCompressor()
        data = compressor.begin() + b"".join(compressor.compress(piece) for _ in range(inflated_mib)) + \
            compressor.flush()
    crafted_mcap(path, FIELDS, [block_at(T0)])
    original = path.read_bytes()
    at = first_chunk_offset(original)
    length = int.from_bytes(original[at + 1 : at + 9], "little")
    record = _chunk_record(compression.removesuffix("-unsized"), data, claimed)
    path.write_bytes(original[:at] + record + original[at + 9 + length :])
    return path


def crafted_mcap_files(folder: Path) -> list[Path]:
    """Every crafted MCAP shape: claims, notes, times, sizes."""
    shapes: list[tuple[str, dict[str, str], list[ChunkBatch], str | None]] = [
        ("notes-table", {**FIELDS, "notes": '{"a": 1}'}, [block_at(T0)], None),
        ("notes-numbers", {**FIELDS, "notes": "[1, 2]"}, [block_at(T0)], None),
        ("notes-newlines", {**FIELDS, "notes": '["a\\n1700000000.0 0103", "\\u00e9t\\u00e9"]'}, [block_at(T0)], None),
        ("late-notes", FIELDS, [block_at(T0)], "nope"),
        ("times-back", FIELDS, [block_at(T0, T0 + 10), block_at(T0 + 5)], None),
        ("times-negative", FIELDS, [block_at(-5, 0)], None),
        ("times-2262", FIELDS, [block_at(2**63 - 10)], None),
        ("no-line", {**FIELDS, "line": ""}, [block_at(T0)], None),
        ("bad-version", {**FIELDS, "format_version": "99"}, [block_at(T0)], None),
        ("big-read", FIELDS, [block_at(T0, data=bytes(3 * 2**20))], None),
    ]
    made = [crafted_mcap(folder / f"crafted-{name}.mcap", fields, blocks, late)
            for name, fields, blocks, late in shapes]
    bombs = [inflate_bomb(folder / f"crafted-{kind}-bomb.mcap", kind) for kind in ("zstd", "zstd-unsized", "lz4")]
    return [*made, *bombs, chunk_bomb(folder / "crafted-bomb.mcap")]


def hostile_text_files(folder: Path) -> list[Path]:
    """Text captures of hostile sizes and times."""
    head = "# rtu-capture v1\n# line: 19200 8E1\n# timing: host\n"
    shapes = {
        "time-5000-digits": head + "1" * 5000 + ".0 0103\n",
        "time-2262": head + "9223372037.0 0103\n",
        "noise-3MB": head + "1700000000.0 " + os.urandom(3_000_000).hex() + "\n",
        "note-newlines": head + "# note \\x0a1700000000.0 0103\n1700000000.0 0103\n",
        "binary": head + "1700000000.0 01\x00\xff03\n",
        "decreasing": head + "1700000001.0 01\n1700000000.0 03\n",
    }
    made = []
    for name, text in shapes.items():
        path = folder / f"hostile-{name}.log"
        path.write_bytes(text.encode("latin-1"))
        made.append(path)
    return made


HEAD = "[profile]\nid='x'\nname='x'\nsources=['m']\n"
#: Hostile profiles and the words of their one error.
HOSTILE_PROFILES: list[tuple[str, str]] = [
    (HEAD + "x = " + "[" * 500 + "]" * 500 + "\n", "nests 500 levels deep"),
    (HEAD + "a" + ".a" * 20_000 + " = 1\n", "nests 20000 levels deep"),
    (HEAD + '"=".a' + ".a" * 20_000 + " = 1\n", "nests 20001 levels deep"),  # a quoted '=' hid the dots
    (HEAD + "x = {" + "a.a." * 10_000 + "a = 1}\n", "nests 20000 levels deep"),
    ("parameter = [1, 2]\n" + HEAD, "parameter[0]: 1 is not a table"),  # top-level keys come first
    (HEAD + "[exception]\ncode = 2\n", "file.exception: {'code': 2} is not a list"),
    (HEAD + "[[exception]]\ncode = 2\nexplanation = 'e'\nsource = 's'\n[exception.addresses]\na = 1\n",
     "exception[0].addresses: {'a': 1} is not a list"),
    (HEAD + "[[exception]]\ncode = 2\nexplanation = 'e'\nsource = 's'\naddresses = [1, 'two']\n",
     "exception[0].addresses[1]: 'two' is not a whole number"),
    ("bitfield = {b = 3}\n" + HEAD, "bitfield.b: 3 is not a table"),
    (HEAD + "[[indirection]]\nprefix = 'N'\naddress_registers = 1\nvalue_registers = 9\ncount = 300000000\n"
     "source = 's'\n", "indirection[0].count: 300000000 is outside 1..125"),
    (HEAD + "notes = ['" + "n" * 5000 + "', 3]\n", "profile.notes[1]: 3 is not text"),
    (HEAD + "x = '" + "y" * (2**20) + "'\n", "a profile has at most 1,048,576"),
    (HEAD + "[[parameter]]\ncode='A'\nname='a'\naddress=1\nsource='s'\nscale = nan\n", "scale"),
]


def hostile_profile_texts() -> list[str]:
    return [text for text, _ in HOSTILE_PROFILES]


FORGED = "1700000000.5 01 06 00 01 00 03 98 0B"
HOSTILE_NAMES: list[tuple[str, ...]] = [
    (f"RX\n{FORGED}", "TX"),
    ("Channel 0", "Channel 1"),
    ("", "-"),
    ("#", "%41", "%"),
    ("Empfänger", "Sender ⚡"),
    ("# channel: TX", "\r\x00\x1b[2J"),
]


def two_line_mcap(path: Path, names: tuple[str, ...]) -> Path:
    """A native MCAP whose lines carry ``names``: a request on the first, its answer on the second."""
    writer = open_writer(str(path), CaptureInfo(LINE, TimingQuality.EXACT, (), names), "mcap")
    chunks = [Chunk(1_700_000_000_000_000_000, bytes.fromhex("010300000001840A"), channel=1),
              Chunk(1_700_000_000_010_000_000, bytes.fromhex("01030200056B87"), channel=len(names))]
    writer.write_batch(ChunkBatch.from_chunks(chunks))
    writer.close()
    return path


def sigrok_session(path: Path, metadata: str, samples: bytes = bytes(1000), repeats: int = 1,
             comment_mib: int = 0) -> Path:
    """A .sr zip with ``metadata`` (and ``comment_mib`` MiB of comment lines after it) and one
    sample file of ``samples`` ``repeats`` times, written piece by piece (a zip bomb made
    without holding it)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as session:
        session.writestr("version", "2")
        with session.open("metadata", "w", force_zip64=True) as entry:
            entry.write(metadata.encode())
            for _ in range(comment_mib):
                entry.write(b"#" * 2**20)
        with session.open("logic-1-1", "w", force_zip64=True) as entry:
            for _ in range(repeats):
                entry.write(samples)
    return path


DEVICE = "[device 1]\ncapturefile=logic-1\ntotal probes=2\nsamplerate=1 MHz\nunitsize=1\nprobe1=RX\nprobe2=TX\n"


def classic_pcap(records: list[tuple[int, bytes, int]]) -> bytes:
    """A classic nanosecond pcap, link type 147: (seconds, bytes, declared captured length)."""
    import struct

    out = struct.pack("<IHHiIII", 0xA1B23C4D, 2, 4, 0, 0, 65535, 147)
    for seconds, data, declared in records:
        out += struct.pack("<IIII", seconds, 0, declared, len(data)) + data
    return out


def pcapng_of(tsresol: int, ticks: int) -> bytes:
    import struct

    def block(kind: int, body: bytes) -> bytes:
        body += bytes(-len(body) % 4)
        return struct.pack("<II", kind, len(body) + 12) + body + struct.pack("<I", len(body) + 12)

    section = block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1))
    interface = block(1, struct.pack("<HHI", 147, 0, 65535) + struct.pack("<HHB3x", 9, 1, tsresol) + bytes(4))
    frame = bytes.fromhex("010300000001840A")
    packet = block(6, struct.pack("<IIIII", 0, ticks >> 32, ticks & 0xFFFFFFFF, len(frame), len(frame)) + frame)
    return section + interface + packet


def many_registers(path: Path, reads: int) -> Path:
    """A capture of ``reads`` answered reads of 125 registers, each at addresses of its own:
    as many wide columns as values, each row holding 125 of them."""
    from decoders.crc import crc_bytes

    def frame(body: bytes) -> str:
        return (body + crc_bytes(body)).hex(" ").upper()

    lines = []
    for read in range(reads):
        t = 1_700_000_000 + read * 0.2
        address = read * 125
        lines.append(f"{t:.6f} {frame(bytes([1, 3]) + address.to_bytes(2, 'big') + (125).to_bytes(2, 'big'))}")
        lines.append(f"{t + 0.1:.6f} {frame(bytes([1, 3, 250]) + bytes(250))}")
    path.write_text("# rtu-capture v1\n# line: 115200 8N1\n# timing: exact\n" + "\n".join(lines) + "\n")
    return path


#: sigrok session metadata that once gave tracebacks, and the words of its one error (None: it reads).
HOSTILE_SESSION_METADATA: list[tuple[str, str | None]] = [
    (DEVICE.replace("unitsize=1", "unitsize=0"), "unitsize '0' is not 1 to 8"),
    (DEVICE.replace("unitsize=1", "unitsize=x"), "unitsize 'x' is not 1 to 8"),
    (DEVICE.replace("1 MHz", "0 Hz"), "samplerate '0 Hz' is not a rate"),
    (DEVICE.replace("1 MHz", "1.2.3 MHz"), "samplerate '1.2.3 MHz' is not a rate"),
    (DEVICE.replace("1 MHz", "99999999999999999999999 GHz"), "is not a rate"),
    (DEVICE + "probe0=\n", "'probe0' is no probe of a session of 1-byte samples"),
    (DEVICE + f"probe{'9' * 5000}=A\n", "is no probe of a session"),
    (DEVICE + "probe٣=A\n", None),  # not an ASCII probe key: no probe, read as sigrok would ignore it
]


def hostile_pcaps() -> list[tuple[str, str, bytes, int, str]]:
    """pcap and pcapng files that once broke the reader: (case, file name, bytes, exit code, words)."""
    return [
        ("4 GiB record", "c.pcap", classic_pcap([(1, b"\x01\x03", 2**32 - 1)]), 7,
         "record 1: a record that holds one read of 4,294,967,295"),
        ("60 MiB record", "c.pcap", classic_pcap([(1, bytes(60 * 2**20), 60 * 2**20)]), 7,
         "over the 1 MiB rtusniff reads"),
        ("4 GiB block", "c.pcapng", pcapng_of(6, 1)[:60] + b"\x06\x00\x00\x00\xfc\xff\xff\xff", 7,
         "a block that holds one read of 4,294,967,280"),
        ("tsresol 10^0", "c.pcapng", pcapng_of(0, 2**63), 7, "beyond the year 2262"),
        ("tsresol 2^-127", "c.pcapng", pcapng_of(0x80 | 127, 2**64 - 1), 0, ""),
        ("tsresol 10^-127", "c.pcapng", pcapng_of(127, 2**64 - 1), 0, ""),
    ]


#: sigrok-cli annotation lines that are none of sigrok's, and the words of their one error.
HOSTILE_ANNOTATION_LINES: list[tuple[str, str]] = [
    ("1" * 5000 + "-" + "2" * 5000 + ' uart-1: rx-data: "01"', "not a sigrok-cli annotation line"),
    ('١٢-٣٤ uart-1: rx-data: "01"', "not a sigrok-cli annotation line"),
    ('12-34 uart-1: rx-data: "0x1"', "'0x1' is not a byte"),
    ('12-34 uart-1: rx-data: "1_2"', "'1_2' is not a byte"),
    ('12-34 uart-1: q7-data: "01"', "class 'q7-data' is neither rx-data nor tx-data"),
]
