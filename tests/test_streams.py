"""Live viewers: a file replayed into Foxglove (its WebSocket protocol, spoken by a test client)
and into a receiving Rerun process, compared with the file exports of the same capture."""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from tests.foxglove_client import FoxgloveClient

pytestmark = pytest.mark.filterwarnings("ignore:RRD file has no footer")

SAMPLE = Path(__file__).resolve().parents[1] / "captures" / "atv71-plc-poll.mcap"
RERUN = Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
#: The Rerun CLI writes no analytics files with CI set (docs/ecosystem-notes).
QUIET_ENV = {**os.environ, "CI": "1"}
WAIT_S = 60


def rerun_receiver(path: Path) -> tuple[subprocess.Popen[bytes], int]:
    """A Rerun process that saves what SDKs send it (the CLI, as a viewer would receive it).

    Started with SIGINT at its default: a shell's background job ignores SIGINT, an ignored
    signal stays ignored across exec, and the CLI then never closes its file on Ctrl-C."""
    port = _free_port()
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        # A group of its own: the ``rerun`` script runs the viewer binary as its child, and a
        # signal to the group reaches both, as Ctrl-C on a terminal does.
        process = subprocess.Popen([str(RERUN), "--save", str(path), "--port", str(port), "--bind", "127.0.0.1"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=QUIET_ENV,
                                   start_new_session=os.name != "nt")
    finally:
        signal.signal(signal.SIGINT, previous)
    _wait_for_port(port)
    return process, port


def stop_receiver(process: subprocess.Popen[bytes]) -> None:
    """Ctrl-C (the CLI closes its file on it)."""
    _signal_receiver(process, signal.SIGINT)
    process.wait(timeout=WAIT_S)


def kill_receiver(process: subprocess.Popen[bytes]) -> None:
    """The viewer killed, the binary the script started too (no process left behind)."""
    _signal_receiver(process, getattr(signal, "SIGKILL", signal.SIGTERM))
    process.wait(timeout=WAIT_S)


def _signal_receiver(process: subprocess.Popen[bytes], number: int) -> None:
    if os.name == "nt":
        process.send_signal(number)
    else:
        os.killpg(process.pid, number)


def rtusniff(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "sniffer", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=QUIET_ENV)


def foxglove_url(process: subprocess.Popen[str], said: list[str] | None = None) -> str:
    """The address a process serves Foxglove on (port 0: the one it chose), from its standard error."""
    assert process.stderr is not None
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stderr], [], [], 0.1)
        if ready:
            line = process.stderr.readline()
            if said is not None:
                said.append(line)
            found = re.search(r"Foxglove: open (ws://\S+)", line)
            if found:
                return found.group(1)
            if not line and process.poll() is not None:
                break
    process.kill()
    raise AssertionError(f"no Foxglove address said: {said}")


def mcap_messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    by_topic: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            by_topic.setdefault(channel.topic, []).append((message.log_time, message.data))
    return by_topic


def test_a_replay_into_foxglove_carries_the_mcap_exports_channels(tmp_path: Path) -> None:
    """One command writes the MCAP file and serves the same channels: a test client subscribed as
    the Foxglove app does gets every frame, transaction, log line and parameter value the file has,
    with the same schemas, times and payloads."""
    exported = tmp_path / "poll.mcap"
    process = rtusniff("export", str(SAMPLE), "--mcap", str(exported), "--foxglove", "0", "--speed", "4",
                       "--profile", "atv71")
    said: list[str] = []
    with FoxgloveClient(foxglove_url(process, said)) as client:
        _, err = process.communicate(timeout=WAIT_S)
        assert process.returncode == 0, err
        time.sleep(0.5)
    assert client.error is None
    assert "served 52 frames to Foxglove" in err
    in_file = mcap_messages(exported)
    for topic in ("/modbus/frames", "/modbus/transactions", "/modbus/log"):
        assert client.messages[topic] == in_file[topic], topic
    slaves = [topic for topic in in_file if topic.startswith("/slave/")]
    for topic in slaves:
        # A slave's channel is advertised when it first carries values, and a client subscribes
        # on the advertisement: the channel holds its values until then, so none is missed (9
        # of 10, 8 of 9, 4 of 5 arrived before).
        assert client.messages[topic] == in_file[topic], topic
    assert slaves
    schemas = {channel["topic"]: (channel["schemaName"], channel["encoding"]) for channel in client.channels.values()}
    assert schemas["/modbus/frames"] == ("rtusniff.Frame", "json")
    assert schemas["/modbus/log"] == ("foxglove.Log", "protobuf")
    assert "/rtusniff/raw_chunks" not in schemas  # the capture itself is for files, not viewers


@pytest.mark.parametrize("subscribe_after_s", [0.0, 1.5])
def test_a_replay_keeps_to_the_captures_time(subscribe_after_s: float) -> None:
    """--speed 4: a capture of about 2.7 s arrives over about 0.66 s, each frame at its time
    counted from the viewer's subscription, however late the viewer comes (the decoding
    process's clock once started at launch: a viewer 1.5 s late got the whole replay at once).
    A busy machine may only delay a frame, so each frame's lower bound is exact."""
    process = rtusniff("analyze", str(SAMPLE), "--foxglove", "0", "--speed", "4", "--format", "jsonl")
    url = foxglove_url(process)
    time.sleep(subscribe_after_s)
    with FoxgloveClient(url) as client:
        out, err = process.communicate(timeout=WAIT_S)
        assert process.returncode == 0, err
    times = [t for t, _ in client.messages["/modbus/frames"]]
    arrivals = client.arrivals["/modbus/frames"]
    assert len(times) == 52 == sum(1 for line in out.splitlines() if '"kind":"frame"' in line)
    assert client.subscribed_at is not None
    # A frame is due when its last byte is: its start time plus up to 256 bytes at 19200 Bd.
    early = [i for i, (t, arrived) in enumerate(zip(times, arrivals, strict=True))
             if arrived - client.subscribed_at < (t - times[0]) / 1e9 / 4 - 0.15 / 4]
    assert not early, f"frames {early} arrived before their time"
    span = (times[-1] - times[0]) / 1e9 / 4
    assert arrivals[-1] - arrivals[0] < span + 1.0


def test_rerun_stream_gets_what_the_rrd_file_gets(tmp_path: Path) -> None:
    """A receiving Rerun process (the CLI saving what it gets, sent in rounds as a live viewer
    is) holds the entities, rows and values of a plain ``export --rrd`` of the same capture."""
    from tests.test_exports import _rerun_rows

    received, written = tmp_path / "received.rrd", tmp_path / "written.rrd"
    viewer, port = rerun_receiver(received)
    try:
        plain = rtusniff("export", str(SAMPLE), "--rrd", str(written), "--profile", "atv71")
        assert plain.wait(timeout=WAIT_S) == 0
        process = rtusniff("export", str(SAMPLE), "--rerun", f"127.0.0.1:{port}", "--speed", "max", "--profile",
                           "atv71")
        _, err = process.communicate(timeout=WAIT_S)
        assert process.returncode == 0, err
        assert f"Rerun: streaming to rerun+http://127.0.0.1:{port}/proxy" in err
        assert "sent 52 frames to the Rerun viewer" in err
    finally:
        stop_receiver(viewer)
    got, expected = _rerun_rows(received), _rerun_rows(written)
    assert _rows_by_entity(got[0]) == _rows_by_entity(expected[0])
    assert got[1] == expected[1] and got[2] == expected[2]
    assert "/slaves/20/params/NMA1" in got[1] and "/bus/load_percent" in got[1]


def _rows_by_entity(chunks: list[tuple[str, int]]) -> Counter[str]:
    rows: Counter[str] = Counter()
    for entity, count in chunks:
        rows[entity] += count
    return rows


def _free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _wait_for_port(port: int) -> None:
    import socket

    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        with socket.socket() as probe:
            if probe.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise AssertionError(f"nothing listens on port {port}")


@pytest.mark.parametrize(("args", "said"), [
    (["--foxglove", "99999"], "--foxglove 99999: give a port"),
    (["--rerun", "nowhere"], "--rerun nowhere: give 'spawn'"),
    (["--speed", "0", "--foxglove", "0"], "--speed 0: give a factor above 0"),
    (["--speed", "fast", "--rerun", "9876"], "--speed fast"),
    (["--foxglove", "0", "--jobs", "2"], "--jobs 2 with a paced replay"),
    (["--speed", "2", "--jobs", "2"], "--jobs 2 with a paced replay"),
])
def test_wrong_stream_options_are_one_line(args: list[str], said: str) -> None:
    process = rtusniff("analyze", str(SAMPLE), *args)
    _, err = process.communicate(timeout=WAIT_S)
    assert process.returncode == 2 and err.count("\n") == 1 and said in err, err


def test_a_taken_port_is_one_line() -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        process = rtusniff("analyze", str(SAMPLE), "--foxglove", str(taken.getsockname()[1]))
        _, err = process.communicate(timeout=WAIT_S)
    assert process.returncode != 0 and err.count("\n") == 1 and "cannot serve Foxglove" in err, err


def _json_lines(text: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


def test_web_pages_of_other_origins_cannot_watch_the_bus() -> None:
    """A page at evil.example open in the user's browser gets 403 and nothing of the bus (one
    line says so); the Foxglove app's origin, a desktop shell's and a program without one get in."""
    process = rtusniff("analyze", str(SAMPLE), "--foxglove", "0", "--speed", "8", "--format", "jsonl")
    said: list[str] = []
    url = foxglove_url(process, said)
    evil = [FoxgloveClient(url, origin=origin)
            for origin in ("http://evil.example", "null", "https://app.foxglove.dev.evil.example")]
    for client in evil:
        with client:
            client._thread.join(timeout=10)
    origins = ("https://app.foxglove.dev", "file://", None)
    app, shell, program = (FoxgloveClient(url, origin=origin) for origin in origins)
    with app, shell, program:
        _, err = process.communicate(timeout=WAIT_S)
        time.sleep(0.5)
    assert process.returncode == 0, err
    for client in evil:
        assert "403" in str(client.error) and client.server_info is None and not client.messages, client.error
    refused = [line for line in said + err.splitlines() if "refused a client" in line]
    assert len(refused) == 3 and "'http://evil.example' is not the Foxglove app's" in refused[0], refused
    for client in (app, shell, program):
        assert client.error is None and len(client.messages["/modbus/frames"]) == 52


def test_a_token_keeps_out_who_was_not_given_the_url() -> None:
    process = rtusniff("analyze", str(SAMPLE), "--foxglove", "0", "--foxglove-token", "--speed", "8")
    url = foxglove_url(process)
    assert re.fullmatch(r"ws://127\.0\.0\.1:\d+/\?token=[A-Za-z0-9_-]{22}", url), url
    with FoxgloveClient(url.split("?")[0]) as without, FoxgloveClient(url.replace("token=", "token=x")) as wrong:
        without._thread.join(timeout=10)
        wrong._thread.join(timeout=10)
    with FoxgloveClient(url) as given:
        _, err = process.communicate(timeout=WAIT_S)
        time.sleep(0.5)
    assert "403" in str(without.error) and "403" in str(wrong.error)
    assert given.error is None and len(given.messages["/modbus/frames"]) == 52, err


@pytest.mark.parametrize(("origin", "target", "token", "refused"), [
    (None, "/", None, False),
    ("https://app.foxglove.dev", "/", None, False),
    ("https://APP.foxglove.dev/", "/", None, False),
    ("file://", "/", None, False),
    ("app://foxglove", "/", None, False),
    ("https://foxglove.example.com", "/", None, True),
    ("http://localhost:8080", "/", None, True),
    ("null", "/", None, True),
    (None, "/", "s3cret-s3cret-s3cret", True),
    (None, "/?token=s3cret-s3cret-s3cret", "s3cret-s3cret-s3cret", False),
    ("http://evil.example", "/?token=s3cret-s3cret-s3cret", "s3cret-s3cret-s3cret", True),
])
def test_who_the_door_lets_in(origin: str | None, target: str, token: str | None, refused: bool) -> None:
    from sniffer.exports.foxglove_gate import FOXGLOVE_ORIGINS, refusal

    assert (refusal(origin, target, FOXGLOVE_ORIGINS, token) is not None) == refused


def test_the_sdk_server_listens_where_no_page_guesses() -> None:
    from sniffer.exports.foxglove_gate import inner_host

    hosts = {inner_host() for _ in range(5)}
    if sys.platform.startswith("linux"):
        assert "127.0.0.1" not in hosts and len(hosts) > 1
    assert all(host.startswith("127.") for host in hosts)


@pytest.mark.parametrize(("args", "said"), [
    (["--foxglove-token", "abc"], "--foxglove-token and --foxglove-allow-origin go with --foxglove"),
    (["--foxglove", "0", "--foxglove-token", "short"], "--foxglove-token: at least 16"),
    (["--foxglove", "0", "--foxglove-allow-origin", "evil.example"], "--foxglove-allow-origin evil.example: give"),
])
def test_wrong_door_options_are_one_line(args: list[str], said: str) -> None:
    process = rtusniff("analyze", str(SAMPLE), *args)
    _, err = process.communicate(timeout=WAIT_S)
    assert process.returncode == 2 and err.count("\n") == 1 and said in err, err
