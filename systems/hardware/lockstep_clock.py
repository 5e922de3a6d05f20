"""The lockstep clock of an emulated controller: while a stream of SERVO targets is tracked,
the controller's time advances by the targets' own intervals instead of the host clock.

Each accepted target grants its interval (the time the PC means between it and the previous
target); the simulation thread steps until the next step would pass the granted time and
then waits for the next target. So the emulated arm moves exactly as far as the stream has
said time has passed, however the OS schedules the PC and the emulator: a tracking verdict
then depends on the commands and the simulation only. Outside a stream (before the first
target, braking after STOP or a timeout, idle) no target says what time it is, and the
simulation keeps the host's real time.
"""

from __future__ import annotations

import threading
import time

import numpy as np

WAIT_SLICE = 0.05  # s; how often a wait re-checks whether the emulator closes


class LockstepClock:
    """How far the simulation may step. Shares the controller's lock (`changed` is a Condition
    on it): every method is called with that lock held."""

    def __init__(self, lock: threading.Lock) -> None:
        self.changed = threading.Condition(lock)
        self.granted: float | None = None  # controller time (s) the stream has granted
        self._caught_up = False  # the simulation waits at the last step within `granted`
        self._closed = False
        self._last_grant_host = -np.inf  # time.monotonic() of the latest grant (s)

    def Grant(self, now: float, interval: float) -> None:
        """A target `interval` s after the previous one (after controller time `now` when a
        stream starts): returns once the simulation stands at the last step within the new
        granted time, or the clock was released or closed meanwhile."""
        self.granted = (now if self.granted is None else self.granted) + interval
        self._last_grant_host = time.monotonic()
        self._caught_up = False
        self.changed.notify_all()
        while not (self._caught_up or self.granted is None or self._closed):
            self.changed.wait(WAIT_SLICE)

    def Release(self) -> None:
        """The stream ended (STOP, timeout): the simulation follows the host clock again."""
        self.granted = None
        self.changed.notify_all()

    def Blocks(self, t_next: float) -> bool:
        """Whether the simulation must wait before stepping to t_next (s); telling a waiting
        Grant that the simulation has caught up when it must."""
        blocks = not self._closed and self.granted is not None and t_next > self.granted + 1e-9
        if blocks and not self._caught_up:
            self._caught_up = True
            self.changed.notify_all()
        return blocks

    def SilentFor(self) -> float:
        """Host seconds since the latest grant."""
        return time.monotonic() - self._last_grant_host

    def Close(self) -> None:
        self._closed = True
        self.changed.notify_all()
