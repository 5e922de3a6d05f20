"""The Universal Robots RTDE wire protocol, version 2 (outputs, and the input registers a
control client such as ur_rtde's RTDEControlInterface writes).

Every packet is `uint16 size` (bytes, header included), `uint8 type`, payload; all fields
big-endian. A client requests the protocol version, reads the controller version, sets up an
output recipe (frequency in Hz + comma-separated variable names; the reply carries the recipe
id and the comma-separated types), sends START and then receives DATA_PACKAGEs: recipe id
followed by the variables packed in recipe order. A control client also sets up input
recipes (comma-separated names; the reply carries the recipe id, numbered from 1 in the
order of the setups, and the types) and sends DATA_PACKAGEs of them, which write the
controller's input registers.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from guidedarm.systems.errors import GuidedArmError

PROTOCOL_VERSION = 2
HEADER = struct.Struct(">HB")

REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
CONTROL_PACKAGE_SETUP_OUTPUTS = ord("O")
CONTROL_PACKAGE_SETUP_INPUTS = ord("I")
CONTROL_PACKAGE_START = ord("S")
CONTROL_PACKAGE_PAUSE = ord("P")

# Struct codes per RTDE type name.
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

# Types of the output variables the double serves (names as in the UR RTDE guide).
OUTPUT_TYPES = {
    "timestamp": "DOUBLE",
    "actual_q": "VECTOR6D",
    "actual_qd": "VECTOR6D",
    "target_q": "VECTOR6D",
    "target_qd": "VECTOR6D",
    "actual_TCP_pose": "VECTOR6D",
    "robot_mode": "INT32",
    "safety_mode": "INT32",
    "runtime_state": "UINT32",
    "robot_status_bits": "UINT32",
    "safety_status_bits": "UINT32",
}


# Registers 0..47 (the upper 24 are the fieldbus-free range).
_REGISTER = re.compile(r"(input|output)_(int|double)_register_(\d+)$")


def VariableType(name: str, direction: str = "output") -> str:
    """The RTDE type of an output (or input) variable, or NOT_FOUND as the controller
    answers for names it does not serve."""
    match = _REGISTER.match(name)
    if match and match[1] == direction and int(match[3]) < 48:
        return "INT32" if match[2] == "int" else "DOUBLE"
    if direction == "output":
        return OUTPUT_TYPES.get(name, "NOT_FOUND")
    return "NOT_FOUND"


class RtdeProtocolError(GuidedArmError):
    """A packet that does not follow the RTDE protocol (truncated, unknown type, bad size)."""


@dataclass(frozen=True)
class Packet:
    type: int
    payload: bytes


def EncodePacket(packet_type: int, payload: bytes = b"") -> bytes:
    """Header + payload of one packet."""
    return HEADER.pack(HEADER.size + len(payload), packet_type) + payload


def SplitPackets(buffer: bytearray) -> list[Packet]:
    """Removes the complete packets at the front of `buffer` (a partial tail stays)."""
    packets = []
    while len(buffer) >= HEADER.size:
        size, packet_type = HEADER.unpack_from(buffer)
        if size < HEADER.size:
            buffer.clear()
            raise RtdeProtocolError(f"RTDE packet size {size} is smaller than its header")
        if len(buffer) < size:
            break
        packets.append(Packet(packet_type, bytes(buffer[HEADER.size : size])))
        del buffer[:size]
    return packets


def RecipeFormat(types: list[str]) -> struct.Struct:
    """The struct of a data package's variables (after the recipe id byte)."""
    try:
        return struct.Struct(">" + "".join(TYPE_FORMATS[t] for t in types))
    except KeyError as e:
        raise RtdeProtocolError(f"RTDE type {e.args[0]} is not supported") from None


def EncodeDataPackage(recipe_id: int, recipe: struct.Struct, values: list) -> bytes:
    """A DATA_PACKAGE with `values` (scalars and sequences, flattened in recipe order)."""
    flat: list = []
    for value in values:
        flat.extend(value if isinstance(value, list | tuple) else [value])
    return EncodePacket(DATA_PACKAGE, bytes([recipe_id]) + recipe.pack(*flat))


def DecodeDataPackage(recipe: struct.Struct, types: list[str], payload: bytes) -> list:
    """The values of a DATA_PACKAGE's payload after its recipe id (vectors as lists)."""
    if len(payload) != recipe.size:
        raise RtdeProtocolError(f"data package of {len(payload)} B, its recipe has {recipe.size}")
    flat = list(recipe.unpack(payload))
    values = []
    for type_name in types:
        count = struct.calcsize(">" + TYPE_FORMATS[type_name]) // struct.calcsize(
            ">" + TYPE_FORMATS[type_name][-1]
        )
        values.append(flat[:count] if count > 1 else flat[0])
        del flat[:count]
    return values
