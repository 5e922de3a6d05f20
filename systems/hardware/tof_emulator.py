"""A ToF tool emulator: streams protocol lines of simulated readings into a pseudo-terminal,
so the serial transport reads them through a real tty device."""

from __future__ import annotations

import os
import threading
import time
import tty
from collections.abc import Callable

import numpy as np

from guidedarm.systems.hardware.tof_protocol import FormatTofLine

# Returns (ranges m, VL6180X status codes) of the six sensors at the moment of the call.
ReadingSource = Callable[[], tuple[np.ndarray, np.ndarray]]


class ToFEmulator:
    """Writes protocol lines into a pseudo-terminal; `device` is the tty path a driver opens.

    With a `source`, a thread writes one line of its reading every `period` s on the host
    clock. Without one, the caller writes each line with Write when its reading leaves the
    tool (the Nachi emulator's simulation thread: a simulated range's end of ranging plus
    the tool's readout and transfer latency), so the lines keep the simulation's time.
    `corrupt_every` > 0 truncates every n-th line (for malformed-line tests)."""

    def __init__(
        self, source: ReadingSource | None, period: float = 0.0, corrupt_every: int = 0
    ) -> None:
        self._master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no CR/LF translation: the bytes pass as the MCU sent them
        # A tool keeps streaming whether or not anyone reads: lines that find the pty's
        # buffer full are lost (counted in `dropped`), never waited for, so that a pty
        # nobody reads cannot stall the simulation thread that writes them.
        os.set_blocking(self._master, False)
        self.dropped = 0
        self.device = os.ttyname(slave)
        self._slave = slave
        self._source = source
        self._period = period
        self._corrupt_every = corrupt_every
        self.lines = 0
        self._closing = threading.Event()
        self._thread = None
        if source is not None:
            self._thread = threading.Thread(target=self._Run, name="tof-emulator", daemon=True)
            self._thread.start()

    def Write(self, ranges: np.ndarray, status: np.ndarray) -> bool:
        """Writes the line of one reading (m, status codes) now; False once the pty is
        closed."""
        ranges_mm = np.clip(np.round(1e3 * np.asarray(ranges)), 0, 255)
        line = FormatTofLine(self.lines, ranges_mm, np.asarray(status)) + "\r\n"
        self.lines += 1
        if self._corrupt_every and self.lines % self._corrupt_every == 0:
            line = line[: len(line) // 2]
        try:
            os.write(self._master, line.encode("ascii"))
        except BlockingIOError:
            self.dropped += 1
        except OSError:
            return False
        return True

    def _Run(self) -> None:
        next_time = time.monotonic()
        while not self._closing.wait(max(0.0, next_time - time.monotonic())):
            next_time += self._period
            if not self.Write(*self._source()):
                return

    def close(self) -> None:
        """Stops the stream and closes the pty; a second call does nothing."""
        if self._closing.is_set():
            return
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        os.close(self._master)
        os.close(self._slave)
