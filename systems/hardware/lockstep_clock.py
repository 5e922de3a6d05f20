"""The lockstep clock of an emulated controller: while a stream of SERVO targets is tracked,
the controller's time advances by the targets' own intervals instead of the host clock.

Each accepted target grants its interval (the time the PC means between it and the previous
target); the simulation thread steps until the next step would pass the granted time and
then waits for the next target. So the emulated arm moves exactly as far as the stream has
said time has passed, however the OS schedules the PC and the emulator: a tracking verdict
then depends on the commands and the simulation only. Outside a stream (before the first
target, braking after STOP or a timeout, idle) no target says what time it is, and the
simulation keeps the host's real time. Between targets time stands still, so nothing
moves while the PC is late, and nothing times out either.
"""

from __future__ import annotations

import threading

# s; times closer than this are the same instant: sums of intervals and multiples of a step
# that should meet (a target's end, a ToF line's due time, a step) differ by rounding only,
# and in lockstep they meet at every step.
SAME_INSTANT = 1e-9


class LockstepClock:
    """How far the simulation may step. Shares the controller's lock (`changed` is a Condition
    on it): every method is called with that lock held."""

    def __init__(self, lock: threading.Lock) -> None:
        self.changed = threading.Condition(lock)
        self.granted: float | None = None  # controller time (s) the stream has granted
        self._caught_up = False  # the simulation waits at the last step within `granted`
        self._closed = False

    def Grant(self, now: float, interval: float) -> None:
        """A target `interval` s after the previous one (after controller time `now` when a
        stream starts): returns once the simulation stands at the last step within the new
        granted time, or the clock was released or closed meanwhile."""
        self.granted = (now if self.granted is None else self.granted) + interval
        self._caught_up = False
        self.changed.notify_all()
        while not (self._caught_up or self.granted is None or self._closed):
            self.changed.wait()

    def Release(self) -> None:
        """The stream ended (STOP, timeout): the simulation follows the host clock again."""
        self.granted = None
        self.changed.notify_all()

    def Blocks(self, t_next: float) -> bool:
        """Whether the simulation must wait before stepping to t_next (s); telling a waiting
        Grant that the simulation has caught up when it must."""
        granted = self.granted
        blocks = not self._closed and granted is not None and t_next > granted + SAME_INSTANT
        if blocks and not self._caught_up:
            self._caught_up = True
            self.changed.notify_all()
        return blocks

    def Close(self) -> None:
        self._closed = True
        self.changed.notify_all()
