"""Device profiles: the shipped files validate, and they name the manuals' frames as the manuals do."""

from __future__ import annotations

import struct
from collections.abc import Callable
from importlib.resources import files
from pathlib import Path

import pytest

from benchmarks.hostile_inputs import HEAD, HOSTILE_PROFILES
from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.capture import ChunkBatch, TimingQuality
from decoders.crc import crc_bytes
from decoders.line import LineSettings
from decoders.message import Message
from decoders.pipeline import decode
from decoders.profiles.parse import ProfileError, parse_profile
from sniffer.profiles_io import profile_book, shipped_profiles
from tests.conftest import ROOT, CliResult

LINE = LineSettings.parse("19200 8E1")
MS = 1_000_000


def run(frames: list[bytes], *profiles: str) -> list[Message]:
    chunks = list(exact_chunks([Transmission(f, 5 * MS) for f in frames], LINE, 0))
    return list(decode([ChunkBatch.from_chunks(chunks)], LINE, TimingQuality.EXACT, profile_book(list(profiles), [])))


def with_crc(body: bytes) -> bytes:
    return body + crc_bytes(body)


def values(message: Message) -> list[tuple[str | None, object, str | None]]:
    return [(p.code, p.value, p.unit) for p in message.params]


def test_every_shipped_profile_validates() -> None:
    profiles = shipped_profiles()
    assert set(profiles) == {"generic", "atv71", "atv312", "nord-sk", "xbt"}
    for profile in profiles.values():
        assert profile.sources and all(p.source for p in profile.parameters.values()), profile.id
        assert len({p.code for p in profile.parameters.values()}) == len(profile.parameters)
        for parameter in profile.parameters.values():
            assert parameter.bitfield is None or parameter.bitfield in profile.bitfields


BAD = [
    ("[profile]\nid='x'\nname='x'\n", "profile: missing 'sources'"),
    ("[profile]\nid='x'\nname='x'\nsources=[]\n", "cite at least one source"),
    ("[profile]\nid='x'\nname='x'\nsources=['m']\n[[parameter]]\ncode='A'\nname='a'\naddress=1\n", "missing 'source'"),
    ("[profile]\nid='x'\nname='x'\nsources=['m']\n[[parameter]]\ncode='A'\nname='a'\naddress=1\nsource='s'\n"
     "[[parameter]]\ncode='B'\nname='b'\naddress=1\nsource='s'\n", "address 1 is already A"),
    ("[profile]\nid='x'\nname='x'\nsources=['m']\n[[parameter]]\ncode='A'\nname='a'\naddress=70000\nsource='s'\n",
     "70000 is outside 0..65535"),
    ("[profile]\nid='x'\nname='x'\nsources=['m']\n[[parameter]]\ncode='A'\nname='a'\naddress=1\nsource='s'\n"
     "bitfield='nope'\n", "no [bitfield.nope]"),
    ("[profile]\nid='x'\nname='x'\nsources=['m']\n[[parameter]]\ncode='A'\nname='a'\naddress=1\nsource='s'\n"
     "access='maybe'\n", "'maybe' is not one of r, rw, w"),
    ("[profile\n", "TOML"),
]


@pytest.mark.parametrize(("text", "words"), BAD)
def test_format_errors_name_the_place(text: str, words: str) -> None:
    with pytest.raises(ProfileError) as caught:
        parse_profile(text, "my.toml")
    assert str(caught.value).startswith("my.toml: ") and words in str(caught.value)


def test_atv71_read_with_scales(manual_frames: dict[str, bytes]) -> None:
    _, answer = run([manual_frames["A1"], manual_frames["A2"]], "atv71")
    assert values(answer) == [("SFr", 4.0, "kHz"), ("tFr", 60.0, "Hz"), ("HSP", 50.0, "Hz"), ("LSP", 0.0, "Hz")]
    assert answer.summary.endswith("SFr = 4.0 kHz, tFr = 60.0 Hz, HSP = 50.0 Hz, LSP = 0.0 Hz")


def test_atv71_writes(manual_frames: dict[str, bytes]) -> None:
    acc, _, both, _ = run([manual_frames[k] for k in ("A7", "A7", "A9", "A10")], "atv71")
    assert values(acc) == [("ACC", 13, "s")]
    assert values(both) == [("ACC", 20, "s"), ("DEC", 30, "s")]


def test_atv71_protected_and_missing_parameters(manual_frames: dict[str, bytes]) -> None:
    _, partly, _, protected, _, refused = run(
        [manual_frames[k] for k in ("A17", "A18", "A17", "A19", "A17", "A20")], "atv71"
    )
    protected_text = "non-existent or protected parameter"
    assert values(partly) == [(None, protected_text, None), ("CHCF", "I/O profile", None),
                              ("COP", "copy of the command word", None)]
    assert values(protected)[1] == ("CHCF", protected_text, None)
    assert "8400 = 16#8000 non-existent or protected parameter" in partly.summary
    assert any("every parameter of a read block is non-existent or protected" in r for r in refused.remarks)


def test_atv71_writing_read_only_eta(manual_frames: dict[str, bytes]) -> None:
    _, exception = run([manual_frames["A15"], manual_frames["A16"]], "atv71")
    assert exception.exception_code == 4
    assert any("ETA (W3201) is read-only" in r for r in exception.remarks)


def test_status_and_control_words() -> None:
    read = with_crc(bytes.fromhex("02030C810001"))
    answer = with_crc(bytes.fromhex("0203028637"))
    command = with_crc(bytes.fromhex("02062135000F"))
    _, eta, cmd, _ = run([read, answer, command, command], "atv71")
    assert values(eta) == [("ETA", "operation enabled, reference reached, reverse", None)]
    assert values(cmd) == [("CMD", "enable operation, forward", None)]
    assert "ETA = 16#8637 operation enabled, reference reached, reverse" in eta.summary


def test_scanner_learnt_from_the_traffic(manual_frames: dict[str, bytes]) -> None:
    """The manual's example: NMA1-8 = ETA, RFRD, LCR, OTR, ULN, THD, THR, LFT;
    NCA1-6 = CMD, LFRD, HSP, LSP, ACC, DEC."""
    nma = (3201, 8604, 3204, 3205, 3207, 3209, 9630, 7121)
    nca = (8501, 8602, 3104, 3105, 9001, 9002)
    setup = []
    for address, table in ((12701, nma), (12721, nca)):
        setup += [with_crc(struct.pack(">BBHH", 20, 3, address, len(table))),
                  with_crc(struct.pack(f">BBB{len(table)}H", 20, 3, 2 * len(table), *table))]
    messages = run([*setup, manual_frames["A13"], manual_frames["A14"]], "atv71")
    request, answer = messages[-2:]
    assert [p.code for p in answer.params] == [f"NM{i}→{c}" for i, c in enumerate(
        ["ETA", "RFRD", "LCR", "OTR", "ULN", "THD", "THR", "LFT"], 1)]
    assert answer.params[1].value == 5000 and answer.params[1].unit == "rpm"
    written = {p.code: p.value for p in request.params if p.raw is not None}
    assert written["NC1→CMD"] == "enable operation, forward"
    assert (written["NC3→HSP"], written["NC5→ACC"]) == (800.0, 1200)


def test_scanner_factory_assignment(manual_frames: dict[str, bytes]) -> None:
    _, answer = run([manual_frames["A13"], manual_frames["A14"]], "atv71")
    assert [p.code for p in answer.params[:3]] == ["NM1→ETA", "NM2→RFRD", "NM3"]
    assert answer.params[2].name == "NM3 (unassigned)"


def test_device_limits_are_flagged() -> None:
    too_many = with_crc(struct.pack(">BBHH", 2, 3, 3102, 70))
    unsupported = with_crc(struct.pack(">BBHH", 2, 4, 0, 2))
    broadcast_read = with_crc(struct.pack(">BBHH", 0, 3, 3102, 1))
    first, second, third = run([too_many, unsupported, broadcast_read], "atv71")
    assert "reads 70 words; Schneider Electric Altivar 61/71 reads at most 63" in first.remarks
    assert "Schneider Electric Altivar 61/71 does not support function 4 (expect exception 01)" in second.remarks
    assert "Schneider Electric Altivar 61/71 takes broadcasts only for functions 6, 16" in third.remarks
    assert "⚠" not in first.summary  # remarks are their own field; the table shows them


def test_identification_picks_the_profile(manual_frames: dict[str, bytes]) -> None:
    messages = run([manual_frames["B4"], manual_frames["B5"], manual_frames["B1"], manual_frames["B2"]])
    device = messages[1].device
    assert device is not None and (device.product_code, device.profile, device.applied) == (
        "ATV31HU09M3S232", "atv312", True)
    assert values(messages[3])[2] == ("HSP", 50.0, "Hz")


def test_chosen_profile_is_not_overridden_by_identification(manual_frames: dict[str, bytes]) -> None:
    messages = run([manual_frames["A11"], manual_frames["A12"], manual_frames["A1"], manual_frames["A2"]], "2=generic")
    assert messages[1].device is not None and not messages[1].device.applied
    assert all(p.code is None for p in messages[3].params)


def test_nord_process_data() -> None:
    """The English edition's FC 16 example: P050[1..3] written at 16#0C81."""
    request = bytes.fromhex("08100C81000306 03E8 07D0 0BB8 F5DF".replace(" ", ""))
    response = bytes.fromhex("08100C810003D3E9")
    written, _ = run([request, response], "nord-sk")
    assert [(p.code, p.raw) for p in written.params] == [("STW", 1000), ("SW1", 2000), ("SW2", 3000)]


def test_xbt_names_registers_as_the_hmi_does(manual_frames: dict[str, bytes]) -> None:
    request, answer = run([manual_frames["A3"], manual_frames["A4"]], "xbt")
    assert [(p.code, p.name) for p in request.params] == [(f"%MW{i}", f"4{i + 1:05d}") for i in range(20, 25)]
    assert answer.params[0].value == 0x54


def test_cli_profile_options(cli: Callable[..., CliResult], tmp_path: Path) -> None:
    from tests.conftest import SAMPLE_LOG

    custom = tmp_path / "pump.toml"
    custom.write_text('[profile]\nid = "pump"\nname = "Our pump"\nsources = ["pump manual p. 12"]\n'
                      '[[parameter]]\naddress = 3102\ncode = "PUMP_SPEED"\nname = "Pump speed"\nunit = "%"\n'
                      'scale = 0.5\nsource = "p. 12"\n')
    result = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--profile-file", str(custom),
                 "--profile", "2=pump", "--filter", "slave=2", "--filter", "role=response")
    records = [r for r in result.jsonl() if r["kind"] == "frame"]
    named = [p for r in records for p in r["params"] if p["code"] == "PUMP_SPEED"]
    assert named and named[0]["value"] == 20.0 and named[0]["unit"] == "%"
    assert cli("profiles", "check", str(custom)).code == 0
    bad = tmp_path / "bad.toml"
    bad.write_text("[profile]\nid = 'x'\nname = 'x'\n")
    checked = cli("profiles", "check", str(bad))
    assert checked.code == 12 and "bad.toml: profile: missing 'sources'" in checked.err


@pytest.mark.parametrize(
    ("args", "words"),
    [(["--profile", "atv99"], "unknown profile 'atv99'; known: atv312, atv71, generic, nord-sk, xbt"),
     (["--profile", "300=atv71"], "the slave must be a number from 0 to 247"),
     (["--profile", "\u00b2=atv71"], "the slave must be a number from 0 to 247")],  # a digit to isdigit()
)
def test_bad_profile_options(cli: Callable[..., CliResult], args: list[str], words: str) -> None:
    from tests.conftest import SAMPLE_LOG

    result = cli("analyze", str(SAMPLE_LOG), *args)
    assert result.code == 2 and words in result.err


def test_profiles_command(cli: Callable[..., CliResult]) -> None:
    listed = cli("profiles")
    assert listed.code == 0 and "atv71" in listed.out and "nord-sk" in listed.out
    shown = cli("profiles", "show", "atv71")
    assert "HSP" in shown.out and "16#8000 in a read: non-existent or protected parameter" in shown.out
    assert cli("profiles", "show", "nope").code == 2


def test_profile_texts_are_shown_as_written(cli: Callable[..., CliResult], tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Brackets in a profile's texts and in a path are text, not rich markup (which dropped
    "[drivecom_status]", the bit field a parameter reads as, and "[address_formula]")."""
    monkeypatch.setenv("COLUMNS", "250")  # table cells on one line each
    shown = cli("profiles", "show", "atv71").out
    assert "Status word [drivecom_status]" in shown and "([Profil])" in shown
    assert "(see [address_formula])" in " ".join(cli("profiles", "show", "nord-sk").out.split())
    site = tmp_path / "[site-a]"
    site.mkdir()
    copy = site / "atv71.toml"
    copy.write_bytes(files("decoders.profiles").joinpath("data", "atv71.toml").read_bytes())  # the installed one
    checked = cli("profiles", "check", str(copy))
    said = checked.out.splitlines()  # one line naming the file, however long its path
    assert checked.code == 0 and len(said) == 1 and said[0].startswith(f"{copy}: profile 'atv71' is valid"), said


@pytest.mark.parametrize("scale", ["nan", "inf", "-inf", "0"])
def test_a_scale_must_be_a_finite_number(cli: Callable[..., CliResult], tmp_path: Path, scale: str) -> None:
    """NaN would be written into JSON (not JSON), inf and 0 lose the value."""
    import decoders.profiles

    shipped = Path(decoders.profiles.__file__).parent / "data" / "atv312.toml"  # the installed package's
    broken = tmp_path / "scaled.toml"
    broken.write_text(shipped.read_text().replace("scale = 0.1", f"scale = {scale}", 1))
    checked = cli("profiles", "check", str(broken))
    assert checked.code == 12 and ".scale: must be a finite number other than 0" in checked.err


HOSTILE = HOSTILE_PROFILES


@pytest.mark.parametrize(("text", "words"), HOSTILE, ids=range(len(HOSTILE)))
def test_hostile_profiles_are_one_error_in_little_memory(text: str, words: str) -> None:
    """Each of these gave a traceback, a recursion error or gigabytes (tomllib on 20 000 dotted
    parts, an indirection of 300 M registers): now one error naming the place."""
    import tracemalloc

    tracemalloc.start()
    with pytest.raises(ProfileError) as caught:
        parse_profile(text, "hostile.toml")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert words in str(caught.value) and len(str(caught.value)) < 200, str(caught.value)
    assert peak < 64 * 2**20


def test_brackets_in_comments_and_strings_do_not_count() -> None:
    text = HEAD + "# a drive's note: " + "[" * 40 + "\nnote = '" + "[" * 40 + "'\nother = \"\\\"" + "{" * 40 + "\"\n"
    assert parse_profile(text, "fine.toml").id == "x"


def test_a_hostile_profile_on_the_command_line_is_one_line(cli: Callable[..., CliResult], tmp_path: Path) -> None:
    hostile = tmp_path / "deep.toml"
    hostile.write_text(HOSTILE[0][0])
    result = cli("analyze", str(ROOT / "captures" / "xbt-hmi.log"), "--profile-file", str(hostile))
    assert result.code == 12 and result.err.count("\n") == 1 and "nests 500 levels deep" in result.err
