"""First role guesses from content and order, on the manuals' frames."""

from __future__ import annotations

from decoders.crc import crc_bytes
from decoders.frame import Frame, FrameFlag
from decoders.message import Message, Role
from decoders.modbus.layouts import fits_request, fits_response
from decoders.modbus.roles import RoleGuesser


def classify(*frames: bytes) -> list[Message]:
    guesser = RoleGuesser()
    out = []
    for i, data in enumerate(frames):
        from decoders.crc import crc_ok

        out.append(guesser.classify(Frame(i, i * 10, i * 10 + 5, data, crc_ok(data), FrameFlag.NONE)))
    return out


def test_request_response_pairs(manual_frames: dict[str, bytes]) -> None:
    for request_id, response_id in [("A1", "A2"), ("A3", "A4"), ("A5", "A6"), ("A9", "A10"), ("A11", "A12"),
                                    ("A13", "A14"), ("A17", "A18"), ("B4", "B5")]:
        request, response = classify(manual_frames[request_id], manual_frames[response_id])
        assert (request.role, response.role) == (Role.REQUEST, Role.RESPONSE), request_id
        assert request.slave == response.slave
        assert request.function == response.function


def test_echoes_are_classified_by_order(manual_frames: dict[str, bytes]) -> None:
    for echo_id in ("A7", "A8"):
        echo = manual_frames[echo_id]
        assert fits_request(echo) and fits_response(echo)
        roles = [m.role for m in classify(echo, echo, echo, echo)]
        assert roles == [Role.REQUEST, Role.RESPONSE, Role.REQUEST, Role.RESPONSE]


def test_exceptions(manual_frames: dict[str, bytes]) -> None:
    _, exception = classify(manual_frames["A15"], manual_frames["A16"])
    assert exception.role is Role.EXCEPTION
    assert (exception.function, exception.exception_code) == (16, 4)
    assert "exception 04 Server Device Failure (Write Multiple Registers)" in exception.summary
    [all_protected] = classify(manual_frames["A20"])
    assert (all_protected.function, all_protected.exception_code) == (3, 2)


def test_altivar_fc43_negative_answer_is_an_exception_with_the_mei_echoed() -> None:
    body = bytes([2, 0xAB, 0x0E, 0x02])
    [message] = classify(body + crc_bytes(body))
    assert message.role is Role.EXCEPTION
    assert (message.function, message.exception_code) == (43, 2)


def test_broadcast_and_crc_error(manual_frames: dict[str, bytes]) -> None:
    body = bytes.fromhex("0006232900 0d".replace(" ", ""))
    broadcast, bad = classify(body + crc_bytes(body), manual_frames["B6"])
    assert broadcast.role is Role.BROADCAST
    assert bad.role is Role.REQUEST
    assert bad.summary.startswith("CRC error: ")


def test_fragments_and_misfits() -> None:
    short, misfit = classify(b"\x02\x03", bytes.fromhex("020305000000"))
    assert short.role is Role.UNKNOWN and short.slave == 2 and short.function == 3
    assert misfit.role is Role.UNKNOWN


def test_user_defined_function_is_shown_as_such() -> None:
    body = bytes([5, 66, 1, 2])
    [message] = classify(body + crc_bytes(body))
    assert message.function == 66
    assert "User-defined function 66" in message.summary
