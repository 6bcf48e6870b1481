"""A real Modbus master and slave (pymodbus) over pseudo-terminals, decoded field for field."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.ptylab import SOCAT, Relay, pty_pair, pymodbus_slave, write_text_capture

pytestmark = pytest.mark.skipif(SOCAT is None, reason="needs socat (apt-get install socat; .ci/run installs it)")


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Run a master session through the relay; return what was asked/answered and the decoded records."""
    directory = tmp_path_factory.mktemp("pty")
    with pty_pair(directory, "master") as to_master, pty_pair(directory, "slave") as to_slave:
        with pymodbus_slave(to_slave.b), Relay(to_master.b, to_slave.a, absent=frozenset({9})) as relay:
            operations = run_master(to_master.a)
            time.sleep(0.2)
        capture = directory / "session.log"
        write_text_capture(capture, relay.tap, "pymodbus master and slave over ptys, copied by a relay")
    import io
    from contextlib import redirect_stdout

    from sniffer.cli import main

    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["analyze", str(capture), "--format", "jsonl"]) == 0
    records = [json.loads(line) for line in out.getvalue().splitlines()]
    return operations, records


def run_master(port: Path) -> list[dict[str, Any]]:
    """A pymodbus master runs its session on ``port``; returns what it asked and got."""
    from pymodbus import FramerType
    from pymodbus.client import ModbusSerialClient

    # The master waits 1 s for an answer: the pymodbus slave is a Python process on a loaded machine
    # (CI runs a Spark session beside it). Only slave 9's one request waits it out. (A slave 1 that
    # "never answered" in CI was the relay losing a request's last byte: see ptylab.Relay.)
    client = ModbusSerialClient(str(port), framer=FramerType.RTU, baudrate=19200, parity="N", timeout=1.0,
                                retries=0)
    assert client.connect()
    try:
        return run_operations(client)
    finally:
        client.close()


def run_operations(client: Any) -> list[dict[str, Any]]:
    """Each call with the fields the request carried and what pymodbus got back."""
    done: list[dict[str, Any]] = []

    from pymodbus.exceptions import ModbusIOException

    def call(function: int, request: dict[str, Any], fn: Callable[[], Any], slave: int = 1) -> None:
        entry: dict[str, Any] = {"function": function, "slave": slave, "request": request}
        try:
            result = fn()
        except ModbusIOException:
            entry["no_response"] = True
            done.append(entry)
            return
        if result.isError():
            entry["exception"] = getattr(result, "exception_code", None)
        else:
            entry["registers"] = list(getattr(result, "registers", []) or [])
            entry["bits"] = [int(b) for b in (getattr(result, "bits", []) or [])]
        done.append(entry)
        time.sleep(0.02)

    call(1, {"address": 10, "count": 12}, lambda: client.read_coils(10, count=12))
    call(2, {"address": 0, "count": 5}, lambda: client.read_discrete_inputs(0, count=5))
    call(3, {"address": 0, "count": 4}, lambda: client.read_holding_registers(0, count=4))
    call(4, {"address": 2, "count": 3}, lambda: client.read_input_registers(2, count=3))
    call(5, {"address": 3, "values": [1]}, lambda: client.write_coil(3, True))
    call(6, {"address": 5, "values": [1234]}, lambda: client.write_register(5, 1234))
    call(8, {"sub_function": 0, "data": "3132"}, lambda: client.diag_query_data(b"12"))
    call(15, {"address": 0, "values": [1, 0, 1]}, lambda: client.write_coils(0, [True, False, True]))
    call(16, {"address": 10, "values": [1, 2, 3]}, lambda: client.write_registers(10, [1, 2, 3]))
    call(3, {"address": 10, "count": 3}, lambda: client.read_holding_registers(10, count=3))
    call(23, {"read_address": 0, "read_count": 3, "write_address": 20, "values": [7, 8]},
         lambda: client.readwrite_registers(read_address=0, read_count=3, write_address=20, values=[7, 8]))
    call(43, {"read_code": 1, "object_id": 0}, lambda: client.read_device_information(read_code=1, object_id=0))
    call(3, {"address": 500, "count": 2}, lambda: client.read_holding_registers(500, count=2))  # exception 2
    call(3, {"address": 0, "count": 2}, lambda: client.read_holding_registers(0, count=2, device_id=17), slave=17)
    call(3, {"address": 0, "count": 2}, lambda: client.read_holding_registers(0, count=2, device_id=9), slave=9)
    call(3, {"address": 0, "count": 2}, lambda: client.read_holding_registers(0, count=2))
    return done


def test_every_exchange_is_decoded_and_paired(session: tuple[list[dict[str, Any]], list[dict[str, Any]]]) -> None:
    operations, records = session
    assert_session_decoded(operations, records)


def assert_session_decoded(operations: list[dict[str, Any]], records: list[dict[str, Any]]) -> None:
    """Every request of the master's session decoded, paired and with the values pymodbus saw."""
    frames = [r for r in records if r["kind"] == "frame"]
    assert all(f["crc_ok"] and f["role"] != "noise" for f in frames), [f for f in frames if not f["crc_ok"]]
    requests = [f for f in frames if f["role"] == "request"]
    assert [(r["slave"], r["function"]) for r in requests] == [(op["slave"], op["function"]) for op in operations]
    answers = {f["request_index"]: f for f in frames if f["request_index"] is not None}
    for op, request in zip(operations, requests, strict=True):
        check_request(op, request)
        if op.get("no_response"):  # slave 9 is not on the bus
            assert op["slave"] == 9
            assert request["index"] not in answers and "timeout" in request["flags"]
            continue
        answer = answers[request["index"]]
        # Paired; a pty read is host-timed, so no latency is published (it would be read times).
        assert answer["latency_s"] is None and answer["index"] > request["index"]
        if "exception" in op:
            assert (answer["role"], answer["exception_code"]) == ("exception", op["exception"])
        else:
            assert answer["role"] == "response"
            check_answer(op, answer)


def check_request(op: dict[str, Any], record: dict[str, Any]) -> None:
    expected = op["request"]
    params = {p["address"]: p["raw"] for p in record["params"]}
    if "count" in expected:
        assert sorted(params) == list(range(expected["address"], expected["address"] + expected["count"]))
    if "values" in expected and "read_address" not in expected:
        written = [params[expected["address"] + i] for i in range(len(expected["values"]))]
        assert written == expected["values"]
    if "read_address" in expected:
        assert [params[expected["write_address"] + i] for i in range(2)] == expected["values"]
        assert all(params[expected["read_address"] + i] is None for i in range(expected["read_count"]))
    if op["function"] == 8:
        assert "diagnostics 00 Return Query Data (echo), data 31 32" in record["summary"]
    if op["function"] == 43:
        assert "read device identification (basic) from object 0" in record["summary"]


def check_answer(op: dict[str, Any], record: dict[str, Any]) -> None:
    expected = op["request"]
    values = [p["raw"] for p in record["params"]]
    if op["function"] in (3, 4, 23):
        assert values == op["registers"]
        start = expected.get("read_address", expected.get("address"))
        assert [p["address"] for p in record["params"]] == list(range(start, start + len(values)))
    elif op["function"] in (1, 2):
        assert values == op["bits"][: expected["count"]]
    elif op["function"] in (5, 6):
        assert values == expected["values"]
    elif op["function"] in (15, 16):
        written = range(expected["address"], expected["address"] + len(expected["values"]))
        assert [p["address"] for p in record["params"]] == list(written)
    elif op["function"] == 43:
        assert "VendorName='rtusniff tests'" in record["summary"] and "ProductCode='PTY-1'" in record["summary"]


def test_stats_of_the_session(tmp_path: Path, session: tuple[list[dict[str, Any]], list[dict[str, Any]]]) -> None:
    _, records = session
    summary = records[-1]
    assert summary["kind"] == "summary"
    assert summary["crc_errors"] == 0
    assert summary["roles"]["request"] == 16 and summary["roles"]["exception"] == 1
    assert summary["flags"].get("timeout") == 1
