"""Decoding a sigrok session's samples as UART: samples per second; prints a table.

    python -m benchmarks.bench_sigrok [--repeat 40]

The session is the flow meter's real recording (../shared/real/sigrok/uart/modbus_rtu/flowmeter,
4 MHz, 9600 8N1, 2.5 M samples) repeated ``--repeat`` times into one session of as many sample
files, read by rtusniff's reader (zip, unpacking, the vectorised UART decoder, chunks) and, for
the split of the cost, by the UART decoder alone on samples already unpacked.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from decoders.line import LineSettings
from decoders.uart import UartDecoder
from sniffer.io.base import ReaderOptions
from sniffer.io.sigrok_session import SigrokSessionReader

SOURCE = Path(__file__).resolve().parent.parent.parent / "shared" / "real" / "sigrok" / "uart" / "modbus_rtu" \
    / "flowmeter" / "flowmeter_target0_val0.sr"
LINE = LineSettings.parse("9600 8N1")


def session(folder: Path, repeat: int) -> tuple[Path, int]:
    with zipfile.ZipFile(SOURCE) as source:
        metadata, samples = source.read("metadata"), source.read("logic-1-1")
    path = folder / "long.sr"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as out:
        out.writestr("version", "2")
        out.writestr("metadata", metadata)
        for part in range(repeat):
            out.writestr(f"logic-1-{part + 1}", samples)
    return path, repeat * len(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=40)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path, samples = session(Path(tmp), args.repeat)
        start = time.perf_counter()
        reader = SigrokSessionReader(str(path), ReaderOptions(line=LINE, channels=("RXTX",)))
        characters = sum(len(batch) for batch in reader.batches())
        reader.close()
        whole = time.perf_counter() - start
        with zipfile.ZipFile(SOURCE) as source:
            level = (np.frombuffer(source.read("logic-1-1"), np.uint8) >> 2 & 1).astype(np.bool_)
        decoder = UartDecoder(LINE, 4e6)
        start = time.perf_counter()
        for _ in range(args.repeat):
            decoder.feed(level)
        alone = time.perf_counter() - start
    print(f"{samples / 1e6:,.0f} M samples ({args.repeat} sample files), {characters:,} characters")
    print(f"{'stage':<44} {'seconds':>8} {'M samples/s':>12}")
    print(f"{'reader: unzip, unpack, decode, chunks':<44} {whole:>8.2f} {samples / whole / 1e6:>12.1f}")
    print(f"{'UART decoder alone (samples unpacked)':<44} {alone:>8.2f} {samples / alone / 1e6:>12.1f}")


if __name__ == "__main__":
    main()
