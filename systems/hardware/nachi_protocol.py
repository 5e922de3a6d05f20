"""The line protocol between a PC and the Nachi CFD controller's User Task (docs/nachi_protocol.md).

Printable ASCII lines ending in LF; every request gets exactly one reply line, in order.
Joints travel in degrees, positions in millimetres (the controller's units); this module
converts to SI. Parsers take a line with one character per byte (LineSocket) and reject any
other byte, quoting lines with `ascii()` so that messages and NG replies stay ASCII.
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
SERVO = "SERVO"
MAX_SERVO_INTERVAL = 1.0  # s; a SERVO interval must lie in (0, MAX_SERVO_INTERVAL]

# The word each request's reply starts with (besides `NG`, which may answer any request).
REPLY_WORDS = {READ_JOINTS: "JOINTS", READ_POSE: "POSE", STATUS: "STATUS", ERRORS: "ERRORS"}
REPLY_WORD_DEFAULT = "OK"  # SET_TARGET, MOVE, SERVO, STOP, RESET
NG = "NG"

# Error codes of `NG <code> <text>` replies.
E_UNKNOWN = "E01"
E_MALFORMED = "E02"
E_LIMIT = "E03"
E_NO_TARGET = "E04"
E_STOPPED = "E05"
E_SERVO_STEP = "E06"
E_TIMEOUT = "E07"
E_STREAMING = "E08"


class NachiProtocolError(GuidedArmError):
    """A line that does not follow the protocol (unknown word, wrong count, not a number)."""


@dataclass(frozen=True)
class Request:
    word: str
    values: np.ndarray  # SI: rad for SET_TARGET and SERVO, empty otherwise
    interval: float = 0.0  # s, SERVO only: the time from the previous target to this one


def Quote(line: str, limit: int = 80) -> str:
    """The first `limit` characters of `line`, quoted, non-ASCII and control characters
    escaped (ASCII only)."""
    return ascii(line[:limit])


def _Fields(line: str) -> list[str]:
    """The space-separated fields of a line of printable ASCII of at most MAX_LINE bytes."""
    if len(line) > MAX_LINE:
        raise NachiProtocolError(f"line longer than {MAX_LINE} bytes")
    bad = next((c for c in line if not " " <= c <= "~"), None)
    if bad is not None:
        raise NachiProtocolError(
            f"byte 0x{ord(bad):02x} at column {line.index(bad) + 1} is not printable ASCII: "
            f"{Quote(line)}"
        )
    return line.split(" ")


def _Numbers(fields: list[str], count: int, line: str) -> np.ndarray:
    if len(fields) != count:
        raise NachiProtocolError(f"expected {count} numbers, got {len(fields)}: {Quote(line)}")
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        raise NachiProtocolError(f"not a number in {Quote(line)}") from None
    if not np.all(np.isfinite(values)):
        raise NachiProtocolError(f"non-finite number in {Quote(line)}")
    return values


def ParseRequest(line: str) -> Request:
    """Server side: one request line (without LF)."""
    fields = [f for f in _Fields(line) if f]
    if not fields:
        raise NachiProtocolError("empty line")
    word, arguments = fields[0], fields[1:]
    if word == SET_TARGET:
        return Request(word, np.deg2rad(_Numbers(arguments, NUM_JOINTS, line)))
    if word == SERVO:
        values = _Numbers(arguments, 1 + NUM_JOINTS, line)
        return Request(word, np.deg2rad(values[1:]), float(values[0]))
    if word in (READ_JOINTS, READ_POSE, MOVE, STOP, RESET, STATUS, ERRORS):
        _Numbers(arguments, 0, line)
        return Request(word, np.zeros(0))
    raise NachiProtocolError(f"unknown request {Quote(word)}")


def FormatSetTarget(q: np.ndarray) -> str:
    """Client side: SET_TARGET line for joints q (rad)."""
    return f"{SET_TARGET} " + " ".join(f"{x:.6f}" for x in np.rad2deg(q))


def FormatServo(q: np.ndarray, interval: float) -> str:
    """Client side: SERVO line for joints q (rad) reached `interval` s after the previous
    target."""
    return f"{SERVO} {interval:.4f} " + " ".join(f"{x:.6f}" for x in np.rad2deg(q))


def FormatJoints(t: float, q: np.ndarray) -> str:
    """Server side: reply to READ_JOINTS (controller time t in s, joints q in rad)."""
    return f"JOINTS {t:.4f} " + " ".join(f"{x:.6f}" for x in np.rad2deg(q))


def ParseJoints(line: str) -> tuple[float, np.ndarray]:
    """Client side: (controller time s, joints rad) from a JOINTS reply."""
    fields = [f for f in _Fields(line) if f]
    if not fields or fields[0] != "JOINTS":
        raise NachiProtocolError(f"expected JOINTS, got {Quote(line)}")
    values = _Numbers(fields[1:], 1 + NUM_JOINTS, line)
    return float(values[0]), np.deg2rad(values[1:])


def FormatPose(xyz: np.ndarray, rpy: np.ndarray) -> str:
    """Server side: reply to READ_POSE (flange in base: m, and roll-pitch-yaw rad)."""
    return "POSE " + " ".join(f"{x:.4f}" for x in np.concatenate([1e3 * xyz, np.rad2deg(rpy)]))


def ParsePose(line: str) -> tuple[np.ndarray, np.ndarray]:
    """Client side: (xyz m, roll-pitch-yaw rad) of the flange in base from a POSE reply."""
    fields = [f for f in _Fields(line) if f]
    if not fields or fields[0] != "POSE":
        raise NachiProtocolError(f"expected POSE, got {Quote(line)}")
    values = _Numbers(fields[1:], 6, line)
    return 1e-3 * values[:3], np.deg2rad(values[3:])


def CheckOk(line: str) -> None:
    """Client side: raises NachiProtocolError unless the reply is OK; a streaming timeout
    (E07) says which setting decides it."""
    if line.strip() != "OK":
        hint = ""
        if line.startswith(f"{NG} {E_TIMEOUT}"):
            hint = (
                " (no SERVO reached the controller within its streaming timeout, a User Task "
                "setting; `guidedarm emulate nachi --servo-timeout`)"
            )
        raise NachiProtocolError(f"controller refused: {Quote(line, 120)}{hint}")


def RepliesOutOfStep(request_word: str, line: str) -> bool:
    """Client side: whether `line` is a well-formed reply word that answers another kind of
    request than `request_word` (e.g. `OK` to READ_JOINTS, `JOINTS` to SERVO): the
    controller and the client no longer agree which reply belongs to which request. A line
    that starts with no reply word at all is malformed, not out of step."""
    word = line.split(" ", 1)[0]
    known = {*REPLY_WORDS.values(), REPLY_WORD_DEFAULT, NG}
    expected = REPLY_WORDS.get(request_word, REPLY_WORD_DEFAULT)
    return word in known and word not in (expected, NG)
