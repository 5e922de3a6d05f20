"""The ToF tool's line protocol: six VL6180X ranges and their range-status codes per line.

    $TOF,<seq>,<r1>,<s1>,<r2>,<s2>,<r3>,<s3>,<r4>,<s4>,<r5>,<s5>,<r6>,<s6>*<CS>\\r\\n

r: range in mm (0..255, the sensor's 8-bit result); s: the VL6180X RESULT__RANGE_STATUS
error code (0 = valid); seq: 0..65535, wraps (a line whose seq repeats or lies just behind
the newest is stale and rejected); CS: two hex digits, XOR of the characters between `$` and
`*` (NMEA style). `ToFLineCollector` turns a byte stream, however it is
fragmented (serial reads, BLE notifications of <= 20 bytes), into readings; any other bytes
(binary noise, NUL, non-ASCII, overlong lines) are rejected with a message and counted.
"""

from __future__ import annotations

import string
import threading
import time
from dataclasses import dataclass

import numpy as np

from guidedarm.systems.errors import GuidedArmError
from guidedarm.systems.hardware.line_socket import PrintRejectedLine

NUM_SENSORS = 6
MAX_LINE = 128
SEQ_MODULUS = 65536
# A line up to this many sequence numbers behind the newest held is an old line delivered
# late (a replayed buffer) and is rejected; a larger step back is the tool restarting its
# count, and its line is new.
SEQ_BEHIND = 256

# VL6180X range error codes (datasheet, RESULT__RANGE_STATUS bits 7:4).
RANGE_STATUS = {
    0: "no error",
    1: "VCSEL continuity test",
    2: "VCSEL watchdog test",
    3: "VCSEL watchdog",
    4: "PLL1 lock",
    5: "PLL2 lock",
    6: "early convergence estimate",
    7: "max convergence",
    8: "no target ignore",
    11: "max signal to noise ratio",
    12: "raw ranging algo underflow",
    13: "raw ranging algo overflow",
    14: "ranging algo underflow",
    15: "ranging algo overflow",
}


class ToFLineError(GuidedArmError):
    """A ToF line that is truncated, corrupted or out of range."""


@dataclass(frozen=True)
class ToFReading:
    """One line: sequence number, ranges (m) and status codes per sensor (0 = valid)."""

    seq: int
    ranges: np.ndarray
    status: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        return (self.status == 0).astype(float)


def Checksum(body: str) -> int:
    value = 0
    for character in body.encode("ascii"):
        value ^= character
    return value


def FormatTofLine(seq: int, ranges_mm: np.ndarray, status: np.ndarray) -> str:
    """The line the microcontroller sends (without CR LF)."""
    fields = [f"{int(r)},{int(s)}" for r, s in zip(ranges_mm, status, strict=True)]
    body = f"TOF,{seq % 65536}," + ",".join(fields)
    return f"${body}*{Checksum(body):02X}"


def _Quote(line: str) -> str:
    """The start of a line, quoted, non-ASCII and control characters escaped."""
    return ascii(line[:40])


def _Integer(field: str, base: int = 10) -> int:
    """A field of ASCII digits (int() alone would also take signs, spaces and underscores)."""
    digits = string.hexdigits if base == 16 else string.digits
    if not field or not all(c in digits for c in field):
        raise ValueError(field)
    return int(field, base)


def ParseTofLine(line: str) -> ToFReading:
    """Parses one line (CR LF stripped or not); raises ToFLineError naming the defect."""
    line = line.strip("\r\n")
    if not line.startswith("$TOF,") or "*" not in line:
        raise ToFLineError(f"not a ToF line: {_Quote(line)}")
    bad = next((c for c in line if not " " <= c <= "~"), None)
    if bad is not None:
        raise ToFLineError(f"byte 0x{ord(bad):02x} is not printable ASCII in {_Quote(line)}")
    body, _, checksum = line[1:].rpartition("*")
    try:
        if len(checksum) != 2 or _Integer(checksum, 16) != Checksum(body):
            raise ToFLineError(f"checksum mismatch in {_Quote(line)}")
        numbers = [_Integer(f) for f in body.split(",")[1:]]
    except ValueError:
        raise ToFLineError(f"not an integer field in {_Quote(line)}") from None
    if len(numbers) != 1 + 2 * NUM_SENSORS:
        raise ToFLineError(f"{len(numbers)} fields, expected {1 + 2 * NUM_SENSORS}")
    ranges, status = np.array(numbers[1::2]), np.array(numbers[2::2])
    if numbers[0] > 65535:
        raise ToFLineError(f"sequence number {numbers[0]} outside 0..65535")
    if np.any((ranges < 0) | (ranges > 255)):
        raise ToFLineError(f"range outside 0..255 mm in {_Quote(line)}")
    unknown = [s for s in status if s not in RANGE_STATUS]
    if unknown:
        raise ToFLineError(f"unknown VL6180X status code {unknown[0]}")
    return ToFReading(numbers[0], 1e-3 * ranges, status)


def SequenceProblem(seq: int, previous: int) -> str | None:
    """Why a line numbered `seq` is not newer than the line numbered `previous` (both
    0..65535, wrapping), or None: it repeats it, or it is up to SEQ_BEHIND lines behind."""
    step = (seq - previous) % SEQ_MODULUS
    if step == 0:
        return f"sequence number {seq} repeats the previous line's (stale data)"
    if step >= SEQ_MODULUS - SEQ_BEHIND:
        return f"sequence number {seq} is behind the newest line's {previous} (stale data)"
    return None


class ToFLineCollector:
    """Assembles lines from byte chunks; keeps the newest reading and its host time, and
    counts rejected lines (printing the 1st, 10th, 100th, ...). A line whose sequence
    number repeats the newest reading's or lies just behind it (SequenceProblem) is stale
    and rejected: a tool that resends the same line must not look alive to the driver's
    watchdog."""

    def __init__(self, name: str = "tof") -> None:
        self.name = name
        self.rejected = 0
        self.accepted = 0
        self._buffer = bytearray()
        self._lock = threading.Lock()
        self._latest: tuple[ToFReading, float] | None = None

    def Feed(self, chunk: bytes) -> None:
        self._buffer += chunk
        while (end := self._buffer.find(b"\n")) >= 0 or len(self._buffer) > MAX_LINE:
            cut = end if end >= 0 else len(self._buffer)
            line = bytes(self._buffer[:cut])
            del self._buffer[: cut + 1]
            # A `$` inside a line means the line before it was cut short: reject the
            # fragment and resynchronise on the newest start.
            head, start, last = line.decode("latin-1").rpartition("$")
            for fragment in head.split("$"):
                if fragment.strip():
                    self._Reject(f"truncated line {_Quote(fragment)}")
            if start:
                self._Accept(start + last)
            elif last.strip():
                self._Reject(f"not a ToF line: {_Quote(last)}")

    def _Reject(self, why: str) -> None:
        self.rejected += 1
        PrintRejectedLine(self.name, "line", self.rejected, why)

    def _Accept(self, line: str) -> None:
        try:
            reading = ParseTofLine(line)
        except ToFLineError as e:
            self._Reject(str(e))
            return
        stale = self._latest and SequenceProblem(reading.seq, self._latest[0].seq)
        if stale:
            self._Reject(stale)
            return
        with self._lock:
            self._latest = (reading, time.monotonic())
            self.accepted += 1

    def latest(self) -> tuple[ToFReading, float] | None:
        with self._lock:
            return self._latest
