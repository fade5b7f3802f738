"""RTDE (protocol version 2) wire format: message codes, variable types, packing.

Standard library only, so the RTDE server child process starts fast. Everything
on the wire is big-endian. A message is ``uint16 size`` (header included),
``uint8 type``, then the payload. Units on the wire are the controller's:
metres, radians, seconds.

References: Universal Robots' "Real-Time Data Exchange (RTDE) guide" and the
ur-rtde client (``rtde.cpp``, ``rtde_receive_interface.cpp``), which parses
each variable with its own idea of the type, so the sizes below must match
what it expects.
"""

from __future__ import annotations

import struct

RTDE_PORT = 30004
PROTOCOL_VERSION = 2

REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
CONTROL_PACKAGE_SETUP_OUTPUTS = ord("O")
CONTROL_PACKAGE_SETUP_INPUTS = ord("I")
CONTROL_PACKAGE_START = ord("S")
CONTROL_PACKAGE_PAUSE = ord("P")

HEADER = struct.Struct(">HB")

#: struct format per RTDE type name
TYPE_FORMATS = {
    "BOOL": "?",
    "UINT8": "B",
    "UINT32": "I",
    "UINT64": "Q",
    "INT32": "i",
    "DOUBLE": "d",
    "VECTOR3D": "3d",
    "VECTOR6D": "6d",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
}

#: text-message warning levels (protocol v2)
EXCEPTION_MESSAGE, ERROR_MESSAGE, WARNING_MESSAGE, INFO_MESSAGE = 0, 1, 2, 3


def _output_types() -> dict[str, str]:
    v6 = (
        "target_q target_qd target_qdd target_current target_moment actual_q actual_qd "
        "actual_current joint_control_output actual_TCP_pose actual_TCP_speed actual_TCP_force "
        "target_TCP_pose target_TCP_speed joint_temperatures actual_joint_voltage ft_raw_wrench "
        "payload_inertia actual_current_window"
    )
    doubles = (
        "timestamp actual_execution_time speed_scaling target_speed_fraction actual_momentum "
        "actual_main_voltage actual_robot_voltage actual_robot_current standard_analog_input0 "
        "standard_analog_input1 standard_analog_output0 standard_analog_output1 io_current "
        "tool_analog_input0 tool_analog_input1 tool_output_voltage tool_output_current "
        "tool_temperature tcp_force_scalar payload"
    )
    types = {n: "VECTOR6D" for n in v6.split()}
    types.update({n: "DOUBLE" for n in doubles.split()})
    types.update(
        {n: "VECTOR3D" for n in ("actual_tool_accelerometer", "payload_cog", "elbow_position",
                                  "elbow_velocity")}
    )
    types.update({n: "UINT64" for n in ("actual_digital_input_bits", "actual_digital_output_bits")})
    types.update({n: "INT32" for n in ("robot_mode", "safety_mode", "safety_status")})
    types.update(
        {
            n: "UINT32"
            for n in (
                "runtime_state", "robot_status_bits", "safety_status_bits", "tool_mode",
                "output_bit_registers0_to_31", "output_bit_registers32_to_63",
                "analog_io_types", "euromap67_input_bits", "euromap67_output_bits",
                "input_bit_registers0_to_31", "input_bit_registers32_to_63",
            )
        }
    )
    types.update({"joint_mode": "VECTOR6INT32", "tool_analog_input_types": "UINT8",
                  "tool_output_mode": "UINT8", "tool_digital_output0_mode": "UINT8",
                  "tool_digital_output1_mode": "UINT8", "script_control_line": "UINT32"})
    for i in range(48):
        types[f"output_int_register_{i}"] = "INT32"
        types[f"output_double_register_{i}"] = "DOUBLE"
        types[f"input_int_register_{i}"] = "INT32"
        types[f"input_double_register_{i}"] = "DOUBLE"
    for i in range(64, 128):
        types[f"output_bit_register_{i}"] = "BOOL"
        types[f"input_bit_register_{i}"] = "BOOL"
    return types


#: every output variable the simulator knows, name -> RTDE type
OUTPUT_TYPES = _output_types()


def _input_types() -> dict[str, str]:
    types = {
        "speed_slider_mask": "UINT32",
        "speed_slider_fraction": "DOUBLE",
        "standard_digital_output_mask": "UINT8",
        "standard_digital_output": "UINT8",
        "configurable_digital_output_mask": "UINT8",
        "configurable_digital_output": "UINT8",
        "tool_digital_output_mask": "UINT8",
        "tool_digital_output": "UINT8",
        "standard_analog_output_mask": "UINT8",
        "standard_analog_output_type": "UINT8",
        "standard_analog_output_0": "DOUBLE",
        "standard_analog_output_1": "DOUBLE",
        "input_bit_registers0_to_31": "UINT32",
        "input_bit_registers32_to_63": "UINT32",
        "external_force_torque": "VECTOR6D",
    }
    for i in range(48):
        types[f"input_int_register_{i}"] = "INT32"
        types[f"input_double_register_{i}"] = "DOUBLE"
    for i in range(64, 128):
        types[f"input_bit_register_{i}"] = "BOOL"
    return types


#: input variables a client may set up (values are accepted and ignored)
INPUT_TYPES = _input_types()


def message(kind: int, payload: bytes = b"") -> bytes:
    """One RTDE message: header (size including header, type) and payload."""
    return HEADER.pack(HEADER.size + len(payload), kind) + payload


def split_messages(buf: bytearray) -> list[tuple[int, bytes]]:
    """Remove every complete message from ``buf``; return them as ``(type, payload)``."""
    out = []
    while len(buf) >= HEADER.size:
        size, kind = HEADER.unpack_from(buf)
        if size < HEADER.size:
            raise ValueError(f"RTDE message with impossible size {size}")
        if len(buf) < size:
            break
        out.append((kind, bytes(buf[HEADER.size:size])))
        del buf[:size]
    return out


def text_message(text: str, source: str = "cellcal-sim", level: int = ERROR_MESSAGE) -> bytes:
    """A protocol-v2 TEXT_MESSAGE: length-prefixed message and source, then the level."""
    m, s = text.encode()[:255], source.encode()[:255]
    return message(TEXT_MESSAGE, bytes([len(m)]) + m + bytes([len(s)]) + s + bytes([level]))


def parse_names(payload: bytes) -> list[str]:
    """Comma-separated variable names (ur-rtde leaves a trailing comma)."""
    return [n.strip() for n in payload.decode("ascii", "replace").split(",") if n.strip()]


def pack_value(kind: str, value) -> bytes:
    """Pack one variable of RTDE type ``kind``; vectors take a sequence."""
    fmt = ">" + TYPE_FORMATS[kind]
    if kind.startswith("VECTOR"):
        return struct.pack(fmt, *value)
    return struct.pack(fmt, value)


def unpack_values(types: list[str], payload: bytes) -> list:
    """Unpack consecutive variables of the given RTDE types (inverse of :func:`pack_value`)."""
    out, offset = [], 0
    for kind in types:
        fmt = ">" + TYPE_FORMATS[kind]
        vals = struct.unpack_from(fmt, payload, offset)
        offset += struct.calcsize(fmt)
        out.append(list(vals) if kind.startswith("VECTOR") else vals[0])
    return out
