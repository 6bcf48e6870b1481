"""Modbus function and exception codes with their standard names."""

from __future__ import annotations

#: Bit set in the function code of an exception response.
EXCEPTION_BIT = 0x80
#: Slave address 0: a broadcast, which no slave answers.
BROADCAST_ADDRESS = 0
#: The most registers or coils one request may name (Modbus Application Protocol V1.1b3); a
#: request for more is invalid, and a slave answers it with exception 03.
MAX_QUANTITY: dict[int, int] = {1: 2000, 2: 2000, 3: 125, 4: 125, 15: 1968, 16: 123}
MAX_READ_WRITE_QUANTITY = (125, 121)  # FC 23: read, write
#: The data table each function reads or writes, as summaries name it.
TABLE_NAMES: dict[int, str] = {1: "coils", 2: "inputs", 3: "HR", 4: "IR", 5: "coil", 6: "HR", 15: "coils", 16: "HR",
                               23: "HR"}
#: The Modicon reference base of each table, by the function code that reads or writes it.
REFERENCE_BASE: dict[int, int] = {1: 1, 2: 10001, 3: 40001, 4: 30001, 5: 1, 6: 40001, 15: 1, 16: 40001, 23: 40001}
#: Functions that read or write coils and discrete inputs: bits, a table of their own beside the
#: registers (a coil at 3201 is not register 3201).
BIT_FUNCTIONS = frozenset({1, 2, 5, 15})
#: The data table a function names: 0 registers (holding and input registers, as profiles name
#: them), 1 coils (FC 1, 5, 15), 2 discrete inputs (FC 2).
REGISTERS, COILS, INPUTS = 0, 1, 2
DATA_TABLE: dict[int, int] = {1: COILS, 5: COILS, 15: COILS, 2: INPUTS}

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

#: FC 8, whose sub-function 0 (return query data) echoes any number of bytes.
DIAGNOSTICS = 8

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


#: FC 8 sub-functions (Modbus application protocol V1.1b3, 6.8).
DIAGNOSTIC_NAMES: dict[int, str] = {
    0x00: "Return Query Data (echo)",
    0x01: "Restart Communications Option",
    0x02: "Return Diagnostic Register",
    0x03: "Change ASCII Input Delimiter",
    0x04: "Force Listen Only Mode",
    0x0A: "Clear Counters and Diagnostic Register",
    0x0B: "Return Bus Message Count",
    0x0C: "Return Bus Communication Error Count",
    0x0D: "Return Bus Exception Error Count",
    0x0E: "Return Server Message Count",
    0x0F: "Return Server No Response Count",
    0x10: "Return Server NAK Count",
    0x11: "Return Server Busy Count",
    0x12: "Return Bus Character Overrun Count",
    0x14: "Clear Overrun Counter and Flag",
}

#: FC 43 MEI types.
MEI_NAMES: dict[int, str] = {13: "CANopen General Reference", 14: "Read Device Identification"}

#: FC 43 / MEI 14 read device ID codes.
READ_DEVICE_ID_CODES: dict[int, str] = {1: "basic", 2: "regular", 3: "extended", 4: "specific object"}

#: FC 43 / MEI 14 standard object names (objects 0x07..0x7F are reserved, 0x80.. private).
DEVICE_ID_OBJECTS: dict[int, str] = {
    0x00: "VendorName",
    0x01: "ProductCode",
    0x02: "MajorMinorRevision",
    0x03: "VendorUrl",
    0x04: "ProductName",
    0x05: "ModelName",
    0x06: "UserApplicationName",
}

#: The Altivar's non-standard FC 43 negative answer codes (ATV71 manual, FC 43 section).
ALTIVAR_MEI_ERRORS: dict[int, str] = {
    0: "no error",
    1: "function code, MEI type or read device ID code incorrect",
    2: "object ID incorrect",
}


def diagnostic_name(sub_function: int) -> str:
    return DIAGNOSTIC_NAMES.get(sub_function, f"Sub-function 0x{sub_function:04X}")


def device_id_object_name(object_id: int) -> str:
    if object_id in DEVICE_ID_OBJECTS:
        return DEVICE_ID_OBJECTS[object_id]
    return f"Private object 0x{object_id:02X}" if object_id >= 0x80 else f"Reserved object 0x{object_id:02X}"
