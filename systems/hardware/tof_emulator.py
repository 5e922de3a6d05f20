"""A ToF tool emulator: streams protocol lines of simulated readings into a pseudo-terminal,
so the serial transport reads them through a real tty device."""

from __future__ import annotations

import os
import queue
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

    With a `source`, one line of its reading every `period` s on the emulator's own clock.
    Without one, the lines of the readings given to Publish, each at its host time: the
    caller decides when a reading leaves the tool (e.g. a simulated range's end of ranging
    plus the tool's readout and transfer latency), as a real tool's timing would.
    `corrupt_every` > 0 truncates every n-th line (for malformed-line tests)."""

    def __init__(self, source: ReadingSource | None, period: float, corrupt_every: int = 0) -> None:
        self._master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no CR/LF translation: the bytes pass as the MCU sent them
        self.device = os.ttyname(slave)
        self._slave = slave
        self._source = source
        self._period = period
        self._corrupt_every = corrupt_every
        self._published: queue.SimpleQueue = queue.SimpleQueue()
        self.lines = 0
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Run, name="tof-emulator", daemon=True)
        self._thread.start()

    def Publish(self, ranges: np.ndarray, status: np.ndarray, due: float) -> None:
        """Queues a reading (m, status codes) to be written at host time `due`
        (time.monotonic(), s); without a source only."""
        self._published.put((due, ranges, status))

    def _Next(self, next_time: float) -> tuple[float, tuple | None]:
        """The next line's due time and its reading (None: read the source then)."""
        if self._source is not None:
            return next_time, None
        while not self._closing.is_set():
            try:
                due, ranges, status = self._published.get(timeout=0.05)
            except queue.Empty:
                continue
            return due, (ranges, status)
        return time.monotonic(), None

    def _Run(self) -> None:
        next_time = time.monotonic()
        while not self._closing.is_set():
            due, reading = self._Next(next_time)
            next_time += self._period
            if self._closing.wait(max(0.0, due - time.monotonic())):
                return
            ranges, status = reading if reading is not None else self._source()
            ranges_mm = np.clip(np.round(1e3 * np.asarray(ranges)), 0, 255)
            line = FormatTofLine(self.lines, ranges_mm, np.asarray(status)) + "\r\n"
            self.lines += 1
            if self._corrupt_every and self.lines % self._corrupt_every == 0:
                line = line[: len(line) // 2]
            try:
                os.write(self._master, line.encode("ascii"))
            except OSError:
                return

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=1.0)
        os.close(self._master)
        os.close(self._slave)
