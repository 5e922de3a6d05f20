"""LF-terminated text lines over a TCP socket, with a bound on line length, and the report
of lines a protocol rejects."""

from __future__ import annotations

import socket


class LineSocket:
    """Reads and writes lines. A line is returned with one character per byte (Latin-1,
    trailing CR removed), whatever its bytes: the protocol layer rejects what is not
    printable ASCII, naming it. A line longer than `max_line` bytes is returned cut to
    `max_line + 1` bytes (the rest up to its LF is discarded), so that the protocol layer
    rejects it instead of buffering without bound. A read timeout keeps what was received
    for the next call."""

    def __init__(self, connection: socket.socket, max_line: int = 256) -> None:
        self.connection = connection
        self._max_line = max_line
        self._buffer = bytearray()
        self._discarding = False  # inside an overlong line, until its LF

    def ReadLine(self) -> str:
        """The next line without its LF; raises ConnectionError when the peer closed."""
        while True:
            end = self._buffer.find(b"\n")
            if self._discarding:
                if end >= 0:
                    del self._buffer[: end + 1]
                    self._discarding = False
                    continue
                self._buffer.clear()
            elif end >= 0 and end <= self._max_line:
                line = bytes(self._buffer[:end])
                del self._buffer[: end + 1]
                return line.decode("latin-1").removesuffix("\r")
            elif len(self._buffer) > self._max_line:
                line = bytes(self._buffer[: self._max_line + 1])
                self._discarding = True
                return line.decode("latin-1").removesuffix("\r")
            data = self.connection.recv(4096)
            if not data:
                raise ConnectionError("peer closed the connection")
            self._buffer += data

    def WriteLines(self, *lines: str) -> None:
        """Sends the lines, each followed by LF; characters outside ASCII are escaped."""
        text = "".join(f"{line}\n" for line in lines)
        self.connection.sendall(text.encode("ascii", "backslashreplace"))


def PrintRejectedLine(link: str, what: str, count: int, why: str) -> None:
    """Prints the count-th line `link` rejected (`what`: "line", "reply") and why, for the
    1st, 10th, 100th, ... only: a device sending nothing but bad lines (hundreds a second)
    would otherwise flood the run's output until its watchdog stops the run."""
    if str(count).rstrip("0") == "1":  # a power of ten
        print(f"{link}: rejected {what} #{count}: {why}", flush=True)
