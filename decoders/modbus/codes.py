"""Modbus function and exception codes with their standard names."""

from __future__ import annotations

#: Bit set in the function code of an exception response.
EXCEPTION_BIT = 0x80

FUNCTION_NAMES: dict[int, str] = {
    1: "Read Coils",
    2: "Read Discrete Inputs",
    3: "Read Holding Registers",
    4: "Read Input Registers",
    5: "Write Single Coil",
    6: "Write Single Register",
    7: "Read Exception Status",
    8: "Diagnostics",
    11: "Get Comm Event Counter",
    12: "Get Comm Event Log",
    15: "Write Multiple Coils",
    16: "Write Multiple Registers",
    17: "Report Server ID",
    20: "Read File Record",
    21: "Write File Record",
    22: "Mask Write Register",
    23: "Read/Write Multiple Registers",
    24: "Read FIFO Queue",
    43: "Encapsulated Interface Transport",
}

#: Function codes the specification leaves to users (shown as such, never as errors).
USER_DEFINED_FUNCTIONS = frozenset(range(65, 73)) | frozenset(range(100, 111))

EXCEPTION_NAMES: dict[int, str] = {
    1: "Illegal Function",
    2: "Illegal Data Address",
    3: "Illegal Data Value",
    4: "Server Device Failure",
    5: "Acknowledge",
    6: "Server Device Busy",
    8: "Memory Parity Error",
    10: "Gateway Path Unavailable",
    11: "Gateway Target Device Failed to Respond",
}


def function_name(code: int) -> str:
    """Standard name of a function code (without the exception bit)."""
    if code in FUNCTION_NAMES:
        return FUNCTION_NAMES[code]
    if code in USER_DEFINED_FUNCTIONS:
        return f"User-defined function {code}"
    return f"Unknown function {code}"


def exception_name(code: int) -> str:
    """Standard name of an exception code."""
    return EXCEPTION_NAMES.get(code, f"Unknown exception {code}")
