"""Ctrl-C and SIGTERM during a run: a KeyboardInterrupt at once, and again at the run's next
progress report if Python dropped the first.

Python raises a signal handler's exception wherever the main thread is; raised inside a
finalizer or a weakref callback (e.g. during a garbage collection) it is dropped with an
"Exception ignored" report and the run would go on to its end. The interrupt is therefore
also kept pending until a run reports it (`TakeInterrupt`), and RunContext.progress, which
every simulation loop calls, raises it again.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any

# The names of the signals received and not yet reported ("" for Ctrl-C).
_PENDING: list[str] = []
# Innermost last: True inside DeferredInterrupts (signals are only recorded), False inside
# InterruptsAllowed.
_DEFERRED: list[bool] = []


def InstallInterruptHandlers() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt (naming SIGTERM) and stay pending; a
    KeyboardInterrupt Python cannot raise (or an error raised while handling it) is not
    printed: the interrupt is raised again later."""
    signal.signal(signal.SIGINT, _OnSignal)
    signal.signal(signal.SIGTERM, _OnSignal)
    default_hook = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if not _FromInterrupt(unraisable.exc_value):
            default_hook(unraisable)

    sys.unraisablehook = hook


def _FromInterrupt(error: BaseException | None) -> bool:
    """Whether `error` is a KeyboardInterrupt or was raised while one was handled."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__context__
    return False


def _OnSignal(signum: int, frame: FrameType | None) -> None:
    _PENDING.append("SIGTERM" if signum == signal.SIGTERM else "")
    if not _DEFERRED or not _DEFERRED[-1]:
        raise _Interrupt(_PENDING[-1])


@contextlib.contextmanager
def DeferredInterrupts() -> Iterator[None]:
    """Within it, Ctrl-C and SIGTERM are recorded, not raised: for the last steps of a
    command that must not be cut (a run's summary, the cleanup at exit); they stay pending
    (RaiseIfInterrupted)."""
    _DEFERRED.append(True)
    try:
        yield
    finally:
        _DEFERRED.pop()


@contextlib.contextmanager
def InterruptsAllowed() -> Iterator[None]:
    """Within DeferredInterrupts, a part that Ctrl-C and SIGTERM stop at once (e.g. a
    campaign's jobs, while the cluster's start and shutdown around them are not cut); one
    recorded before it is raised on entry."""
    _DEFERRED.append(False)
    try:
        RaiseIfInterrupted()
        yield
    finally:
        _DEFERRED.pop()


def RaiseIfInterrupted() -> None:
    """Raises the pending interrupt, if any (a safe point of a long loop)."""
    pending = PendingInterrupt()
    if pending is not None:
        raise pending


def PendingInterrupt() -> KeyboardInterrupt | None:
    """The interrupt received and not yet reported (TakeInterrupt), or None."""
    return _Interrupt(_PENDING[-1]) if _PENDING else None


def TakeInterrupt() -> None:
    """Marks the pending interrupts as reported (the run has stopped for them)."""
    _PENDING.clear()


def _Interrupt(name: str) -> KeyboardInterrupt:
    return KeyboardInterrupt(name) if name else KeyboardInterrupt()


@contextlib.contextmanager
def StopOnSignal(stop: Callable[[], None]) -> Iterator[None]:
    """Within `with`, SIGINT and SIGTERM call `stop()` in a thread of their own instead of
    raising: a service that blocks on locks (an emulator waiting for its clock) ends its
    loop normally. A KeyboardInterrupt raised inside a lock's wait can leave the lock
    inconsistent and end the process with a traceback."""

    def handler(signum: int, frame: FrameType | None) -> None:
        threading.Thread(target=stop, name="stop-on-signal", daemon=True).start()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for signum, handler_before in previous.items():
            signal.signal(signum, handler_before)
