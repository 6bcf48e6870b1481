"""Coverage-guided fuzzing with atheris (libFuzzer) of the readers, the framer and the decoders.

    python tests/fuzz/atheris_fuzz.py TARGET [libFuzzer options, e.g. -runs=1000000 -max_len=4096] [CORPUS_DIR]

Targets: ``text``, ``mcap``, ``sigrok`` (a ``.sr`` zip), ``pcap`` (pcap or pcapng) and
``sigrok-cli`` (UART annotations) (bytes as a capture file: it reads cleanly or ends in one
error naming the file), ``mcap-metadata`` (bytes as the fields of an MCAP capture's metadata,
sealed or not: one error, or a capture whose line names and notes come back the same through
the text format), ``framer`` (bytes as timed chunks on a line: every byte comes out in
exactly one frame, in order), ``decoders`` (bytes as frames: matcher, annotator and JSONL
records never raise, and the cached decoding equals decoding each frame), ``profile`` (bytes as
a profile file: a profile or one error naming the place). A crash is any
other exception; libFuzzer then writes the input to ``crash-*`` and exits non-zero. Without a
corpus folder, the file targets and ``profile`` start from the shipped samples (and the real
recordings of ``../shared/real``) and profiles and the hostile shapes of
``benchmarks/hostile_inputs.py``.
The hypothesis tests in tests/property cover the same ground with shaped inputs; atheris
finds the inputs that reach new code.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import json
import pkgutil
import sys
import tempfile
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # run as a script: the repository's tests package


#: The modules each target exercises: only they carry coverage counters. Instrumenting numpy's,
#: pyarrow's and the standard library's as well took 10 s at every start and guided nothing of ours.
INSTRUMENTED = {
    "text": ("sniffer.io", "decoders.capture"),
    "mcap": ("sniffer.io", "decoders.capture"),
    "framer": ("decoders.framer", "decoders.framing", "decoders.frame", "decoders.crc", "decoders.runs",
               "decoders.byte_times", "decoders.capture", "decoders.memo", "decoders.uss", "decoders.modbus.layouts"),
    "decoders": ("decoders.modbus", "decoders.profiles", "decoders.uss", "decoders.uss_pairing", "decoders.frame",
                 "decoders.message", "sniffer.encoding"),
    "profile": ("decoders.profiles",),
    "sigrok": ("sniffer.io", "decoders.capture", "decoders.uart"),
    "pcap": ("sniffer.io", "decoders.capture"),
    "sigrok-cli": ("sniffer.io", "decoders.capture"),
    "mcap-metadata": ("sniffer.io", "decoders.capture"),
}
#: Each file target's suffix (which chooses the reader).
FILE_TARGETS = {"text": ".log", "mcap": ".mcap", "sigrok": ".sr", "pcap": ".pcap", "sigrok-cli": ".ann"}


def import_every_module(*names: str) -> None:
    """Every module of the packages ``names`` (and the modules named), so that those the code
    under test imports only when first used (the capture formats, the MCAP reader, the framer's
    fast paths) are imported inside the instrumenting block too: atheris instruments nothing
    imported after it."""
    for name in names:
        module = importlib.import_module(name)
        for found in pkgutil.walk_packages(getattr(module, "__path__", []), f"{name}."):
            importlib.import_module(found.name)


_instrumented = INSTRUMENTED.get(sys.argv[1] if len(sys.argv) > 1 else "", ("decoders", "sniffer"))
# Every import inside the block, the tests' and benchmarks' too: whichever imports a module of ours
# first decides whether it carries counters (theirs take none: they are not included).
with atheris.instrument_imports(include=list(_instrumented)):
    import_every_module(*_instrumented)
    from benchmarks.hostile_inputs import (
        DEVICE,
        FIELDS,
        T0,
        block_at,
        classic_pcap,
        crafted_mcap,
        crafted_mcap_files,
        hostile_profile_texts,
        pcapng_of,
        sigrok_session,
    )
    from decoders.capture import Chunk, ChunkBatch, TimingQuality
    from decoders.crc import crc_ok
    from decoders.frame import Frame, FrameFlag, frames_to_batch
    from decoders.framer import Framer
    from decoders.line import LineSettings
    from decoders.modbus.annotate import Annotator
    from decoders.modbus.matcher import Matcher
    from decoders.profiles.apply import ProfileApplier
    from decoders.profiles.parse import ProfileError, parse_profile
    from sniffer.encoding.records import FrameRecordEncoder
    from sniffer.errors import RtuSniffError
    from sniffer.io.base import ReaderOptions
    from sniffer.io.mcap_checks import sealed
    from sniffer.io.registry import open_reader, open_writer
    from sniffer.io.text_writer import comment_lines
    from sniffer.profiles_io import profile_book
    from tests.oracles import PlainAnnotator, frame_record
    from tests.property.test_reader_fuzz import read_all, sample_of

SCRATCH = Path(tempfile.mkdtemp(prefix="rtusniff-atheris-"))
SAMPLES = Path(__file__).resolve().parents[2] / "captures"
FIELD_LINE = LineSettings.parse("9600 8N1")
LINES = [LineSettings.parse(text) for text in ("9600 8E1", "19200 8E1", "115200 8N1")]
PROFILES = [[], ["atv71"], ["atv312"], ["nord-sk"], ["xbt"]]


def read_capture(data: bytes, suffix: str) -> None:
    read_all(data, suffix)  # the hypothesis fuzz test's check: reads cleanly, or one line naming the file


def chunks_of(provider: atheris.FuzzedDataProvider) -> list[Chunk]:
    t, chunks = provider.ConsumeIntInRange(0, 2**62), []
    while provider.remaining_bytes() > 2:
        t += provider.ConsumeIntInRange(0, 50_000_000)
        chunks.append(Chunk(t, provider.ConsumeBytes(provider.ConsumeIntInRange(1, 64)) or b"\x00"))
    return chunks


def frame_everything(provider: atheris.FuzzedDataProvider) -> None:
    line = LINES[provider.ConsumeIntInRange(0, len(LINES) - 1)]
    timing = TimingQuality.HOST if provider.ConsumeBool() else TimingQuality.EXACT
    batch_size = provider.ConsumeIntInRange(1, 8)
    chunks = chunks_of(provider)
    framer, frames = Framer(line, timing), []
    for start in range(0, len(chunks), batch_size):
        frames.extend(framer.feed(ChunkBatch.from_chunks(chunks[start : start + batch_size])))
    frames.extend(framer.flush())
    if b"".join(f.data for f in frames) != b"".join(c.data for c in chunks):
        raise AssertionError("bytes lost, doubled or moved by the framer")
    if [f.index for f in frames] != list(range(len(frames))):
        raise AssertionError("frame indices not consecutive")


def decode_frames(provider: atheris.FuzzedDataProvider) -> None:
    choice = PROFILES[provider.ConsumeIntInRange(0, len(PROFILES) - 1)]
    frames, t = [], 0
    while provider.remaining_bytes() > 1:
        t += provider.ConsumeIntInRange(0, 200_000_000)
        data = provider.ConsumeBytes(provider.ConsumeIntInRange(1, 40))
        frames.append(Frame(len(frames), t, t + 1000 * len(data), data, crc_ok(data), FrameFlag.NONE))
    if not frames:
        return
    matcher = Matcher()
    cached, plain = Annotator(ProfileApplier(profile_book(choice, []))), PlainAnnotator(
        ProfileApplier(profile_book(choice, [])))
    encoder = FrameRecordEncoder()
    for batch in (matcher.feed(frames_to_batch(frames)), matcher.flush()):
        expected = [plain.annotate(message) for message in batch]
        annotated = cached.annotate_batch(batch)
        rows = encoder.rows(annotated)
        records = [rows.row(index).decode() for index in range(len(rows))]
        for message, record, reference in zip(annotated, records, expected, strict=True):
            if message.summary != reference.summary or message.params != reference.params:
                raise AssertionError(f"cached decoding differs at frame {message.frame.index}")
            if record != json.dumps(frame_record(message), ensure_ascii=False, separators=(",", ":")):
                raise AssertionError(f"JSONL record differs from json.dumps at frame {message.frame.index}")


def metadata_round_trip(provider: atheris.FuzzedDataProvider) -> None:
    """Fields of an MCAP capture's metadata (often plausible: a line, exact timing, a JSON list of
    line names), sealed or not: the capture is one error, or reads with names and notes that
    the text format gives back the same."""
    fields = {key: provider.ConsumeUnicodeNoSurrogates(24) for key in ("format_version", "timing", "line", "notes",
                                                                        "channels", "writer", "sha256")
              if provider.ConsumeBool()}
    if provider.ConsumeBool():
        names = [provider.ConsumeUnicode(12) for _ in range(provider.ConsumeIntInRange(0, 4))]
        fields |= {**FIELDS, "channels": json.dumps(names), "notes": json.dumps(names[:2])}
    if provider.ConsumeBool():
        fields = sealed({key: value for key, value in fields.items() if key != "sha256"})
    path = crafted_mcap(SCRATCH / "metadata.mcap", fields, [block_at(T0, T0 + 1_000_000)])
    if read_all(path.read_bytes(), ".mcap") < 0:
        return
    reader = open_reader(str(path), options=ReaderOptions(line=FIELD_LINE))  # as read_all: a damaged seal is said
    text = SCRATCH / "metadata.log"
    text.unlink(missing_ok=True)
    try:
        writer = open_writer(str(text), reader.info, "text")
    except RtuSniffError:  # two lines of one name: the text format refuses them, in one line
        reader.close()
        return
    for batch in reader.batches():
        writer.write_batch(batch)
    writer.close()
    back = open_reader(str(text))
    # Names come back as they were; notes too where the format did not have to escape them
    # (a note's line breaks, control and non-ASCII characters are shown escaped, by design).
    plain = all(comment_lines(note) == [f"# {note}"] and note == note.strip() for note in reader.info.notes)
    if back.info.channels != reader.info.channels or (plain and back.info.notes[: len(reader.info.notes)]
                                                      != reader.info.notes):
        raise AssertionError(f"names or notes changed through the text format: {reader.info} → {back.info}")
    reader.close()
    back.close()


def parse_any_profile(data: bytes) -> None:
    """Bytes as a profile file: a profile, or one ProfileError naming the place; nothing else."""
    with contextlib.suppress(ProfileError):
        parse_profile(data.decode("utf-8", "replace"), "fuzzed.toml")


def _seed_corpus(suffix: str) -> Path:
    """A corpus folder holding the shipped samples of one format, and the hostile shapes found
    by the reliability benchmark (crafted MCAPs; hostile profiles beside the shipped ones)."""
    corpus = SCRATCH / f"corpus{suffix}"
    corpus.mkdir()
    if suffix == ".toml":
        for profile in (SAMPLES.parent / "decoders" / "profiles" / "data").glob("*.toml"):
            (corpus / profile.name).write_bytes(profile.read_bytes())
        for number, text in enumerate(hostile_profile_texts()):
            (corpus / f"hostile-{number}.toml").write_text(text[:4096])
        return corpus
    for sample in SAMPLES.glob(f"*{suffix}"):
        (corpus / sample.name).write_bytes(sample.read_bytes())
    if suffix == ".mcap":
        made = SCRATCH / "crafted"
        made.mkdir()
        for crafted in crafted_mcap_files(made):
            if crafted.stat().st_size <= 65536:
                (corpus / crafted.name).write_bytes(crafted.read_bytes())
    for name, data in _hostile_seeds(suffix):
        (corpus / name).write_bytes(data)
    return corpus


def _hostile_seeds(suffix: str) -> list[tuple[str, bytes]]:
    """A real recording of the format (where ``../shared/real`` is beside the checkout) and the
    hostile shapes that once broke its reader."""
    seeds: list[tuple[str, bytes]] = []
    format_of = {".sr": "sigrok", ".pcap": "pcap", ".ann": "sigrok-cli"}
    if suffix in format_of:
        with contextlib.suppress(OSError):
            seeds.append((f"sample{suffix}", sample_of(format_of[suffix])))
    if suffix == ".sr":
        for number, metadata in enumerate([DEVICE, DEVICE.replace("unitsize=1", "unitsize=3"),
                                           DEVICE.replace("1 MHz", "0 Hz"), DEVICE + "probe0=\n"]):
            seeds.append((f"hostile-{number}.sr", sigrok_session(SCRATCH / f"s{number}.sr", metadata).read_bytes()))
    if suffix == ".pcap":
        seeds += [("big-record.pcap", classic_pcap([(1, b"\x01\x03", 2**32 - 1)])),
                  ("resolution.pcap", pcapng_of(0x80 | 127, 2**64 - 1)), ("seconds.pcap", pcapng_of(0, 2**63))]
    if suffix == ".ann":
        seeds += [("digits.ann", '10-20 uart-1: rx-data: "02"\n١٢-٣٤ uart-1: rx-data: "0x1"\n'.encode()),
                  ("directions.ann", "".join(f'{10 * i}-{10 * i + 9} uart-1: d{i}-data: "02"\n'
                                             for i in range(300)).encode())]
    return seeds


def main() -> None:
    targets = {
        **{name: functools.partial(read_capture, suffix=suffix) for name, suffix in FILE_TARGETS.items()},
        "mcap-metadata": lambda data: metadata_round_trip(atheris.FuzzedDataProvider(data)),
        "framer": lambda data: frame_everything(atheris.FuzzedDataProvider(data)),
        "decoders": lambda data: decode_frames(atheris.FuzzedDataProvider(data)),
        "profile": parse_any_profile,
    }
    if len(sys.argv) < 2 or sys.argv[1] not in targets:
        sys.exit(f"usage: {sys.argv[0]} {{{','.join(targets)}}} [libFuzzer options]")
    name = sys.argv.pop(1)
    if (name in FILE_TARGETS or name == "profile") and all(arg.startswith("-") for arg in sys.argv[1:]):
        sys.argv.append(str(_seed_corpus(FILE_TARGETS.get(name, ".toml"))))
    atheris.Setup(sys.argv, targets[name])
    atheris.Fuzz()


if __name__ == "__main__":
    main()
