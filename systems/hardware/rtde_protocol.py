"""The Universal Robots RTDE wire protocol, version 2 (the subset a data-output client uses).

Every packet is `uint16 size` (bytes, header included), `uint8 type`, payload; all fields
big-endian. A client requests the protocol version, reads the controller version, sets up an
output recipe (frequency in Hz + comma-separated variable names; the reply carries the recipe
id and the comma-separated types), sends START and then receives DATA_PACKAGEs: recipe id
followed by the variables packed in recipe order.
"""

from __future__ import annotations

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
