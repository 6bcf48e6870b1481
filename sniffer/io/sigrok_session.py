"""sigrok / PulseView sessions (``.sr``): a logic analyzer's samples, decoded as UART here.

A session is a zip: ``metadata`` (an INI text: sample rate, unit size, the probes' names) and
``logic-1-1``, ``logic-1-2``, … (the samples, ``unitsize`` bytes each, bit ``k`` for probe
``k + 1``). The line's probe is ``--channel`` (a name or a number from 1), or the only one that
changes; a line that idles low is read inverted (:mod:`sniffer.io.polarity`). The UART settings
come from ``--line``; a session does not say them, so without it the standard rates near what the
line's one-bit pulses measure are tried with 8E1, 8N1, 8O1, 8N2 and either polarity, and the
setting that decodes with the fewest errors is taken (a warning says so). Each
character becomes a chunk stamped with the end of its stop bit: exact timing. The session has no
clock time: sample 0 is the time the zip stores for its ``metadata`` (to the second, its zone
unknown, read as UTC). Characters with a framing or parity error are kept, and counted in a warning.
"""

from __future__ import annotations

import configparser
import re
import zipfile
import zlib
from calendar import timegm
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from decoders.capture import GUESSED_LINE, CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from decoders.uart import UartCharacters, UartDecoder, baud_candidates, character_chunks, merge_characters, pulse_baud
from sniffer.errors import CaptureFormatError, ErrorKind, shown
from sniffer.io.base import ChannelChoiceError, ReaderOptions, chosen_channels
from sniffer.io.polarity import chosen_polarity, errors_in

NS_PER_S = 1_000_000_000
#: Samples looked at (whole sample files) to tell the line's settings when ``--line`` does not.
DETECTION_SAMPLES = 4_000_000
#: The character formats tried then, the likelier first (Modbus RTU's default is 8E1).
DETECTED_FORMATS = ("8E1", "8N1", "8O1", "8N2")
_RATE = re.compile(r"([0-9]{1,12}(?:\.[0-9]{1,12})?)\s*([kMG]?)Hz", re.IGNORECASE)
#: Beyond any logic analyzer.
MAX_RATE_HZ = 100e9
#: Sample bytes read at a time: memory stays bounded whatever a sample file holds.
PIECE_BYTES = 16 * 2**20
#: The metadata is a few hundred bytes; more than this is no sigrok metadata.
MAX_METADATA_BYTES = 2**20
_SCALE = {"": 1.0, "k": 1e3, "m": 1e6, "g": 1e9}
#: The earliest date a zip entry can hold (MS-DOS dates).
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


class SigrokSessionReader:
    """Reads a ``.sr`` session's chosen probe as UART characters."""

    def __init__(self, path: str, options: ReaderOptions) -> None:
        self.path = path
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        #: The note saying how the line settings were read from the samples (no --line).
        self._guessed: str | None = None
        try:
            self._zip = zipfile.ZipFile(path)
        except Exception as exc:
            raise self._error(f"not a readable sigrok session (a zip): {exc}") from None
        try:
            self._read_metadata()
            self._probes_used = self._choose_probes(options.channels)
            self._line = self._line_settings(options)
            self._inverted = [self._polarity(probe, options.invert) for probe in self._probes_used]
        except BaseException:
            self._zip.close()
            raise
        self._framing = self._parity = 0
        self._first_error: float | None = None
        probes = ", ".join(f"{self._probes[probe]}{' (inverted)' if inverted else ''}"
                           for probe, inverted in zip(self._probes_used, self._inverted, strict=True))
        # Two probes (RX and TX): each character says which one it came from.
        channels = tuple(self._probes[probe] for probe in self._probes_used) if len(self._probes_used) > 1 else ()
        self.info = CaptureInfo(self._line, TimingQuality.EXACT, (
            f"sigrok session {path}: probe {probes} at {self._rate:,.0f} Hz, decoded as UART "
            f"{self._line.format()} by rtusniff", *([self._guessed] if self._guessed else [])), channels)

    def _start_ns(self, stamp: tuple[int, int, int, int, int, int]) -> int:
        """When the session began: its metadata's date in the zip. Some zip writers leave the
        date zero (month 0), which is no date: the times then count from the earliest a zip
        can hold, 1980-01-01 UTC, and the user is told (the frames and their spacing are the same)."""
        try:
            return timegm(stamp) * NS_PER_S
        except (ValueError, OverflowError):
            self.warnings.append(f"{self.path}: the session's zip gives no valid date for its metadata "
                                 f"({'-'.join(map(str, stamp[:3]))}): times count from 1980-01-01 00:00 UTC")
            return timegm(_ZIP_EPOCH) * NS_PER_S

    def _error(self, message: str, kind: ErrorKind = ErrorKind.BAD_DATA) -> CaptureFormatError:
        return CaptureFormatError(kind, message, path=self.path, location="session")

    def _read_metadata(self) -> None:
        try:
            entry = self._zip.getinfo("metadata")
            if entry.file_size > MAX_METADATA_BYTES:
                raise self._error(f"metadata of {entry.file_size:,} bytes: sigrok writes a few hundred "
                                  f"(read up to {MAX_METADATA_BYTES:,})", ErrorKind.BAD_HEADER)
            with self._zip.open(entry) as metadata:
                text = metadata.read(MAX_METADATA_BYTES).decode("utf-8", "replace")
            stamp = entry.date_time
        except CaptureFormatError:
            raise
        except Exception as exc:
            raise self._error(f"no readable metadata in the zip: {exc}", ErrorKind.BAD_HEADER) from None
        parser = configparser.ConfigParser(interpolation=None, strict=False)
        try:
            parser.read_string(text)
            device = parser["device 1"]
        except (configparser.Error, KeyError):
            raise self._error("metadata has no [device 1] section", ErrorKind.BAD_HEADER) from None
        self._rate = self._sample_rate(device.get("samplerate", ""))
        self._unit = self._unit_size(device.get("unitsize", "1"))
        self._capturefile = device.get("capturefile", "logic-1")
        self._probes = self._probe_names(device)
        if not self._probes:
            analog = device.get("total analog", "0")
            raise self._error("no logic probes (rtusniff decodes digital samples; this session has "
                              f"{analog} analog channels only)", ErrorKind.UNKNOWN_FORMAT)
        self._t0_ns = self._start_ns(stamp)
        names = sorted((name for name in self._zip.namelist() if name.startswith(self._capturefile + "-")),
                       key=lambda name: int(name.rsplit("-", 1)[1]) if name.rsplit("-", 1)[1].isdigit() else 0)
        if not names:
            raise self._error(f"no sample files ({self._capturefile}-1, …) in the zip")
        self._chunks = names

    def _sample_rate(self, text: str) -> float:
        rate = _RATE.fullmatch(text.strip())
        hz = float(rate[1]) * _SCALE[rate[2].lower()] if rate is not None else 0.0
        if not 0 < hz <= MAX_RATE_HZ:
            raise self._error(f"metadata: samplerate {shown(text)} is not a rate (1 Hz to 100 GHz)",
                              ErrorKind.BAD_HEADER)
        return hz

    def _unit_size(self, text: str) -> int:
        if not re.fullmatch(r"[1-8]", text.strip()):
            raise self._error(f"metadata: unitsize {shown(text)} is not 1 to 8 (bytes per sample)",
                              ErrorKind.BAD_HEADER)
        return int(text)

    def _probe_names(self, device: configparser.SectionProxy) -> dict[int, str]:
        """``probeN = NAME`` for each logic probe: N from 1 to the bits a sample holds."""
        probes = {}
        for key, value in device.items():
            number = re.fullmatch(r"probe(\d+)", key, re.ASCII)
            if number is None:
                continue
            if not (len(number[1]) <= 3 and 1 <= int(number[1]) <= 8 * self._unit):
                raise self._error(f"metadata: {shown(key)} is no probe of a session of {self._unit}-byte samples "
                                  f"(probe1 to probe{8 * self._unit})", ErrorKind.BAD_HEADER)
            probes[int(number[1])] = value
        return probes

    def _samples(self, name: str) -> Iterator[np.ndarray]:
        """The samples of one sample file, in pieces of at most :data:`PIECE_BYTES`: a file of
        gigabytes (a long capture, or a zip bomb of a few kilobytes) is read in bounded memory."""
        try:
            with self._zip.open(name) as entry:
                carry = b""
                while raw := entry.read(PIECE_BYTES):
                    raw = carry + raw
                    usable = len(raw) - len(raw) % self._unit
                    carry = raw[usable:]
                    yield self._words(raw[:usable])
        except (zipfile.BadZipFile, OSError, EOFError, zlib.error, NotImplementedError, RuntimeError) as exc:
            raise CaptureFormatError(ErrorKind.BAD_DATA, f"cannot read {name}: {exc}", path=self.path,
                                     location=name) from None

    def _words(self, raw: bytes) -> np.ndarray:
        """Samples as unsigned integers, bit ``k`` for probe ``k + 1`` (3, 5, 6, 7-byte samples
        widened to 4 or 8 bytes)."""
        if self._unit in (1, 2, 4, 8):
            return np.frombuffer(raw, dtype=f"<u{self._unit}")
        width = 4 if self._unit < 4 else 8
        padded = np.zeros((len(raw) // self._unit, width), np.uint8)
        padded[:, : self._unit] = np.frombuffer(raw, np.uint8).reshape(-1, self._unit)
        return padded.view(f"<u{width}").ravel()

    def _pieces(self) -> Iterator[np.ndarray]:
        for name in self._chunks:
            yield from self._samples(name)

    def _level(self, words: np.ndarray, probe: int) -> np.ndarray:
        return ((words >> (probe - 1)) & 1).astype(np.bool_)

    def _choose_probes(self, channels: tuple[str, ...]) -> list[int]:
        if channels:
            try:
                probes, said = chosen_channels(channels, self._probes, "probe")
            except ChannelChoiceError as exc:
                raise self._error(str(exc), ErrorKind.USAGE) from None
            self.warnings += [f"{self.path}: {warning}" for warning in said]
            return probes
        # The probes that change anywhere: the first sample files may hold an idle line only.
        changing: set[int] = set()
        for words in self._pieces():
            changing |= {index for index in self._probes if np.any(np.diff(self._level(words, index)))}
        if len(changing) != 1:
            listed = ", ".join(f"{index}={self._probes[index]}" for index in sorted(changing or self._probes))
            raise self._error(f"{'several' if changing else 'no'} probes change ({listed}); choose the line's "
                              "with --channel NAME or NUMBER (twice for RX and TX)", ErrorKind.USAGE)
        return sorted(changing)

    def _polarity(self, probe: int, forced: bool | None) -> bool:
        """Whether ``probe`` reads inverted, by what its first samples decode to
        (:func:`~sniffer.io.polarity.chosen_polarity`), said in a warning where it is inverted."""
        level = self._first_levels(probe)
        inverted, said = chosen_polarity(lambda inverted: UartDecoder(self._line, self._rate, inverted).feed(level),
                                         starts_low=bool(len(level)) and not bool(level[0]), forced=forced,
                                         name=f"probe {self._probes[probe]}")
        if said is not None:
            self.warnings.append(f"{self.path}: {said}")
        return inverted

    def _first_levels(self, probe: int) -> npt.NDArray[np.bool_]:
        """``probe``'s levels over the first :data:`DETECTION_SAMPLES` samples (whole pieces)."""
        pieces, count = [], 0
        for words in self._pieces():
            pieces.append(self._level(words, probe))
            count += len(pieces[-1])
            if count >= DETECTION_SAMPLES:
                break
        return np.concatenate(pieces) if pieces else np.zeros(0, np.bool_)

    def _line_settings(self, options: ReaderOptions) -> LineSettings:
        """``--line``, else what the samples show: of the standard rates near what the one-bit
        pulses measure (:func:`~decoders.uart.baud_candidates`) and the character formats a Modbus
        line uses, the one that reads with the fewest framing and parity errors (said in a warning,
        with the settings that read as well: ``--line`` makes it sure)."""
        if options.line is not None:
            return options.line
        level = self._first_levels(self._probes_used[0])
        measured = pulse_baud(level, self._rate)
        if measured is None:
            raise self._error("a sigrok session does not say its UART settings, and its samples show too few "
                              "pulses to tell: give --line, e.g. --line 9600 8N1", ErrorKind.NO_LINE_SETTINGS)
        bauds = baud_candidates(measured)
        if not bauds:
            raise self._error(f"a sigrok session does not say its UART settings, and its shortest pulses measure "
                              f"{measured:,.0f} Bd, near no standard rate: give --line", ErrorKind.NO_LINE_SETTINGS)
        scores = []
        # Either way up unless forced: which is the line's own polarity's business (_polarity).
        ways = (False, True) if options.invert is None else (options.invert,)
        for place, (baud, spelled) in enumerate((baud, spelled) for baud in bauds for spelled in DETECTED_FORMATS):
            line = LineSettings.parse(f"{baud} {spelled}")
            for inverted in ways:
                characters = UartDecoder(line, self._rate, inverted).feed(level)
                errors = errors_in(characters)
                scores.append((errors / max(len(characters), 1), place, line, errors, len(characters)))
        share, _, line, errors, count = min(scores, key=lambda score: score[:2])
        if count == 0:
            raise self._error(f"no UART characters at {line.baud} Bd in the first samples: give --line",
                              ErrorKind.NO_LINE_SETTINGS)
        alike = sorted({other.format() for other_share, _, other, _, other_count in scores
                        if other != line and other_count and other_share <= share + 0.01})
        tie = f"; {', '.join(alike)} read as well" if alike else ""
        how = (f"the samples read best as {line.format()} ({errors} of {count} characters with an error in the "
               f"first {len(level):,} samples{tie})")
        self.warnings.append(f"{self.path}: no --line; {how}; give --line to be sure")
        self._guessed = f"{GUESSED_LINE}{how}"
        return line

    def batches(self) -> Iterator[ChunkBatch]:
        decoders = [UartDecoder(self._line, self._rate, inverted) for inverted in self._inverted]
        pending: list[UartCharacters] = []
        read = 0
        for words in self._pieces():
            pending += [self._on_channel(decoder.feed(self._level(words, probe)), channel)
                        for channel, (decoder, probe) in enumerate(zip(decoders, self._probes_used, strict=True), 1)]
            read += len(words)
            # Characters decoded later end after this piece: what ends before it is final in order.
            ready, pending = _merged(pending, before=float(read))
            if ready is not None:
                yield self._chunk_batch(ready)
        ready, _ = _merged(pending, before=float("inf"))
        if ready is not None:
            yield self._chunk_batch(ready)
        if self._framing or self._parity:
            self.warnings.append(f"{self.path}: {self._framing} characters with a framing error, {self._parity} "
                                 f"with a parity error (the first {self._first_error:.6f} s into the session); "
                                 "kept as sampled, each marked with its error")

    def _on_channel(self, characters: UartCharacters, channel: int) -> UartCharacters:
        """``characters`` of the ``channel``-th probe, marked with it when there are several."""
        if not self.info.channels:
            return characters
        return replace(characters, channels=np.full(len(characters), channel, np.uint8))

    def _chunk_batch(self, characters: UartCharacters) -> ChunkBatch:
        errors = characters.framing_errors | characters.parity_errors
        self._framing += int(characters.framing_errors.sum())
        self._parity += int(characters.parity_errors.sum())
        if self._first_error is None and errors.any():
            self._first_error = float(characters.end_samples[np.argmax(errors)]) / self._rate
        return character_chunks(characters, t0_ns=self._t0_ns, unit_s=1.0 / self._rate)

    def last_time_ns(self) -> int | None:
        total = 0
        for name in self._chunks:
            total += self._zip.getinfo(name).file_size // self._unit
        return self._t0_ns + round(total / self._rate * NS_PER_S)

    def close(self) -> None:
        self._zip.close()


def _merged(parts: list[UartCharacters], *, before: float) -> tuple[UartCharacters | None, list[UartCharacters]]:
    """The characters of ``parts`` (probes decoded alike) ending before sample ``before``, in time
    order, and the rest, kept for the next round."""
    merged = merge_characters(parts)
    if not len(merged):
        return None, []
    cut = int(np.searchsorted(merged.end_samples, before, "left"))
    ready, rest = merged.slice(0, cut), merged.slice(cut, len(merged))
    return (ready if len(ready) else None), ([rest] if len(rest) else [])
