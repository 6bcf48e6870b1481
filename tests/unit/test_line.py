import pytest

from decoders.line import LineSettings, Parity


@pytest.mark.parametrize(
    ("text", "bits"),
    [("19200 8E1", 11), ("9600 8N2", 11), ("115200 8N1", 10), ("38400 8O1", 11), ("9600 7E1", 10)],
)
def test_bits_per_char(text: str, bits: int) -> None:
    assert LineSettings.parse(text).bits_per_char == bits


def test_char_time_19200_8e1() -> None:
    line = LineSettings.parse("19200 8E1")
    assert line.char_time_ns == pytest.approx(572_916.667, abs=0.001)
    assert line.t1_5_ns == pytest.approx(1.5 * 572_916.667, abs=0.01)
    assert line.t3_5_ns == pytest.approx(3.5 * 572_916.667, abs=0.01)
    assert not line.uses_fixed_timing


@pytest.mark.parametrize("baud", [38400, 57600, 115200])
def test_fixed_timing_above_19200(baud: int) -> None:
    line = LineSettings.parse(f"{baud} 8N1")
    assert (line.t1_5_ns, line.t3_5_ns) == (750_000.0, 1_750_000.0)
    strict = LineSettings.parse(f"{baud} 8N1", char_timing=True)
    assert strict.t3_5_ns == pytest.approx(3.5 * 10 * 1e9 / baud)
    assert strict.t1_5_ns == pytest.approx(1.5 * 10 * 1e9 / baud)


def test_parse_and_format_round_trip() -> None:
    line = LineSettings.parse("  9600   8o2 ")
    assert line == LineSettings(9600, 8, Parity.ODD, 2)
    assert line.format() == "9600 8O2"


@pytest.mark.parametrize("text", ["19200", "19200 8X1", "19200 9E1", "19200 8E3", "fast 8E1", "0 8N1", "99999999 8N1"])
def test_parse_rejects(text: str) -> None:
    with pytest.raises(ValueError):
        LineSettings.parse(text)


def test_a_tie_in_line_auto_is_never_called_sure() -> None:
    """``--line auto`` on a line where several settings read as well (a pseudo-terminal has no
    baud rate: every setting gave 100 %) called the first of them sure."""
    from sniffer.line_probe import Trial, certainty

    def trial(text: str, valid: int, frames: int = 10) -> Trial:
        return Trial(LineSettings.parse(text), 100, valid, frames)

    assert certainty(trial("19200 8E1", 100), [trial("9600 8E1", 100), trial("19200 8N1", 40)]) == (
        "not sure: 9600 8E1 read as well; the commoner setting is taken")
    assert certainty(trial("19200 8E1", 98), [trial("9600 8E1", 30)]) == "sure"
    assert certainty(trial("19200 8E1", 60), [trial("9600 8E1", 10)]) == "not sure"
