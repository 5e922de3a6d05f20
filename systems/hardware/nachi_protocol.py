"""The line protocol between a PC and the Nachi CFD controller's User Task (docs/nachi_protocol.md).

ASCII lines ending in LF; every request gets exactly one reply line, in order. Joints travel
in degrees, positions in millimetres (the controller's units); this module converts to SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guidedarm.systems.errors import GuidedArmError

NUM_JOINTS = 6
MAX_LINE = 256  # bytes; longer lines are malformed
DEFAULT_PORT = 48000

READ_JOINTS = "READ_JOINTS"
READ_POSE = "READ_POSE"
SET_TARGET = "SET_TARGET"
MOVE = "MOVE"
STOP = "STOP"
RESET = "RESET"
STATUS = "STATUS"
ERRORS = "ERRORS"

# Error codes of `NG <code> <text>` replies.
E_UNKNOWN = "E01"
E_MALFORMED = "E02"
E_LIMIT = "E03"
E_NO_TARGET = "E04"
E_STOPPED = "E05"


class NachiProtocolError(GuidedArmError):
    """A line that does not follow the protocol (unknown word, wrong count, not a number)."""


@dataclass(frozen=True)
class Request:
    word: str
    values: np.ndarray  # SI: rad for SET_TARGET, empty otherwise


def _Numbers(fields: list[str], count: int, line: str) -> np.ndarray:
    if len(fields) != count:
        raise NachiProtocolError(f"expected {count} numbers, got {len(fields)}: {line!r}")
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        raise NachiProtocolError(f"not a number in {line!r}") from None
    if not np.all(np.isfinite(values)):
        raise NachiProtocolError(f"non-finite number in {line!r}")
    return values


def ParseRequest(line: str) -> Request:
    """Server side: one request line (without LF)."""
    if len(line) > MAX_LINE:
        raise NachiProtocolError(f"line longer than {MAX_LINE} bytes")
    fields = line.split()
    if not fields:
        raise NachiProtocolError("empty line")
    word, arguments = fields[0], fields[1:]
    if word == SET_TARGET:
        return Request(word, np.deg2rad(_Numbers(arguments, NUM_JOINTS, line)))
    if word in (READ_JOINTS, READ_POSE, MOVE, STOP, RESET, STATUS, ERRORS):
        _Numbers(arguments, 0, line)
        return Request(word, np.zeros(0))
    raise NachiProtocolError(f"unknown request {word!r}")


def FormatSetTarget(q: np.ndarray) -> str:
    """Client side: SET_TARGET line for joints q (rad)."""
    return f"{SET_TARGET} " + " ".join(f"{x:.6f}" for x in np.rad2deg(q))


def FormatJoints(t: float, q: np.ndarray) -> str:
    """Server side: reply to READ_JOINTS (controller time t in s, joints q in rad)."""
    return f"JOINTS {t:.4f} " + " ".join(f"{x:.6f}" for x in np.rad2deg(q))


def ParseJoints(line: str) -> tuple[float, np.ndarray]:
    """Client side: (controller time s, joints rad) from a JOINTS reply."""
    fields = line.split()
    if not fields or fields[0] != "JOINTS":
        raise NachiProtocolError(f"expected JOINTS, got {line[:80]!r}")
    values = _Numbers(fields[1:], 1 + NUM_JOINTS, line)
    return float(values[0]), np.deg2rad(values[1:])


def FormatPose(xyz: np.ndarray, rpy: np.ndarray) -> str:
    """Server side: reply to READ_POSE (flange in base: m, and roll-pitch-yaw rad)."""
    return "POSE " + " ".join(f"{x:.4f}" for x in np.concatenate([1e3 * xyz, np.rad2deg(rpy)]))


def ParsePose(line: str) -> tuple[np.ndarray, np.ndarray]:
    """Client side: (xyz m, roll-pitch-yaw rad) of the flange in base from a POSE reply."""
    fields = line.split()
    if not fields or fields[0] != "POSE":
        raise NachiProtocolError(f"expected POSE, got {line[:80]!r}")
    values = _Numbers(fields[1:], 6, line)
    return 1e-3 * values[:3], np.deg2rad(values[3:])


def CheckOk(line: str) -> None:
    """Client side: raises NachiProtocolError unless the reply is OK."""
    if line.strip() != "OK":
        raise NachiProtocolError(f"controller refused: {line[:120]!r}")
