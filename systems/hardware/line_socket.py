"""LF-terminated text lines over a TCP socket, with a bound on line length."""

from __future__ import annotations

import socket


class LineSocket:
    """Reads and writes ASCII lines; a line longer than `max_line` bytes is cut and returned
    whole up to that length, so the protocol layer rejects it instead of buffering forever."""

    def __init__(self, connection: socket.socket, max_line: int = 256) -> None:
        self.connection = connection
        self._max_line = max_line
        self._buffer = bytearray()

    def ReadLine(self) -> str:
        """The next line without its LF; raises ConnectionError when the peer closed."""
        while True:
            end = self._buffer.find(b"\n")
            if end >= 0 or len(self._buffer) > self._max_line:
                cut = end if end >= 0 else len(self._buffer)
                line = bytes(self._buffer[:cut])
                if end >= 0:
                    del self._buffer[: cut + 1]
                else:
                    self._DiscardThroughNewline()
                return line.decode("ascii", "replace").rstrip("\r")
            data = self.connection.recv(4096)
            if not data:
                raise ConnectionError("peer closed the connection")
            self._buffer += data

    def _DiscardThroughNewline(self) -> None:
        while (end := self._buffer.find(b"\n")) < 0:
            self._buffer.clear()
            data = self.connection.recv(4096)
            if not data:
                raise ConnectionError("peer closed the connection")
            self._buffer += data
        del self._buffer[: end + 1]

    def DiscardUnread(self) -> None:
        """Drops whatever has arrived but not been read: replies to requests that timed out,
        which would otherwise be taken for the replies to the next request."""
        self._buffer.clear()
        timeout = self.connection.gettimeout()
        self.connection.setblocking(False)
        try:
            while self.connection.recv(4096):
                pass
        except (BlockingIOError, InterruptedError):
            pass
        finally:
            self.connection.settimeout(timeout)

    def WriteLines(self, *lines: str) -> None:
        self.connection.sendall("".join(f"{line}\n" for line in lines).encode("ascii"))
