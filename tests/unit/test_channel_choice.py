"""``--channel``: which channel each option names, said where a name shadows a number; a channel
named twice, or none, refused (:func:`sniffer.io.base.chosen_channels`)."""

from __future__ import annotations

import pytest

from sniffer.io.base import ChannelChoiceError, chosen_channels

#: The probes of the Brainchild recording in ``../shared/real/``.
SIGROK_PROBES = {1: "0", 2: "1"}
SALEAE_COLUMNS = {1: "Channel 0", 2: "Channel 1"}


def test_names_are_matched_before_numbers_and_a_shadowed_number_is_said() -> None:
    assert chosen_channels(("1",), SIGROK_PROBES, "probe") == (
        [2], ["--channel 1 is probe 2, named '1' (a name is matched before a number: probe 1 is named '0')"])
    assert chosen_channels(("Channel 1", "1"), SALEAE_COLUMNS) == ([2, 1], [])


def test_names_that_are_no_number_say_the_others_are_names_too() -> None:
    assert chosen_channels(("0", "1"), SIGROK_PROBES, "probe") == ([1, 2], [])


@pytest.mark.parametrize(("requested", "said"), [
    (("1", "2"), "--channel 1 and --channel 2 both name probe 2 (named '1'"),
    (("0", "0"), "--channel 0 and --channel 0 both name probe 1 (named '0'"),
    (("7",), "--channel 7: no such probe (here: 1=0, 2=1)"),
])
def test_a_probe_named_twice_or_not_at_all_is_refused(requested: tuple[str, ...], said: str) -> None:
    with pytest.raises(ChannelChoiceError, match=said.replace("(", r"\(").replace(")", r"\)")):
        chosen_channels(requested, SIGROK_PROBES, "probe")
