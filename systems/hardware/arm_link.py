"""What an arm driver needs from a robot link, whatever the vendor: the latest measured joint
sample (taken by the link's own I/O thread) and a way to command and to stop the arm.

Every open link is remembered so that a fault anywhere in a hardware diagram (a silent
sensor, a camera delivering the wrong frames) and the end of the process (a finished run,
Ctrl-C, an uncaught error) stop every arm: `StopAllArms`, `FailStoppingAllArms`. A link is
stopped once by whoever handles the fault, and then forgotten.
"""

from __future__ import annotations

import atexit
import gc
import threading
import time
import weakref
from dataclasses import dataclass
from typing import NoReturn, Protocol

import numpy as np

from guidedarm.systems.errors import HardwareFaultError


@dataclass(frozen=True)
class JointSample:
    """Joint positions q (rad) and velocities v (rad/s) received at `host_time`
    (time.monotonic(), s)."""

    q: np.ndarray
    v: np.ndarray
    host_time: float


class LatestSample:
    """The newest JointSample, written by an I/O thread and read by a LeafSystem."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._sample: JointSample | None = None

    def put(self, q: np.ndarray, v: np.ndarray) -> None:
        sample = JointSample(np.array(q, float), np.array(v, float), time.monotonic())
        with self._lock:
            self._sample = sample

    def get(self) -> JointSample | None:
        with self._lock:
            return self._sample


class ArmLink(Protocol):
    """A connection to one arm controller. `send_position` streams a joint position target
    (rad) reached over `period` seconds; `stop` halts the arm, returns within a bounded
    time (raising if the controller did not confirm) and must be safe to repeat; `fault` is
    a one-line reason once the link can no longer be used, else None; `close` releases the
    link and never raises."""

    name: str

    def latest(self) -> JointSample | None: ...

    def fault(self) -> str | None: ...

    def send_position(self, q: np.ndarray, period: float) -> None: ...

    def stop(self) -> None: ...

    def close(self) -> None: ...


_open_links: weakref.WeakSet = weakref.WeakSet()  # not yet stopped
_unclosed_links: weakref.WeakSet = weakref.WeakSet()
_vendor_threads: weakref.WeakSet = weakref.WeakSet()


def RegisterVendorThread(thread: threading.Thread) -> None:
    """Remembers a thread that calls into a vendor's native library (a link's I/O thread, a
    bounded call left behind on a controller that stopped answering), for
    VendorThreadsAlive."""
    _vendor_threads.add(thread)


def VendorThreadsAlive() -> bool:
    """Whether a thread registered with RegisterVendorThread still runs: then the process
    cannot be finalized safely (the interpreter's teardown would destroy objects that a
    native thread still uses) and must end without it (os._exit)."""
    return any(thread.is_alive() for thread in list(_vendor_threads))


def RegisterArmLink(link: ArmLink) -> None:
    """Remembers `link` so that StopAllArms and CloseAllArmLinks reach it (until
    `UnregisterArmLink`)."""
    _open_links.add(link)
    _unclosed_links.add(link)


def UnregisterArmLink(link: ArmLink) -> None:
    """Forgets a closed link."""
    _open_links.discard(link)
    _unclosed_links.discard(link)


def CloseAllArmLinks() -> list[str]:
    """The end of a run in a process that goes on (`guidedarm.diagrams.cli.main.main`
    called from Python, a test): stops every arm not yet stopped, then closes every link,
    which ends its I/O threads. Returns the stop errors as StopAllArms does."""
    errors = StopAllArms()
    for link in list(_unclosed_links):
        link.close()
    return errors


def DescribeError(error: BaseException) -> str:
    """One line for an exception whose text may be empty (e.g. a bare TimeoutError)."""
    return str(error) or type(error).__name__


def StopArm(link: ArmLink) -> str | None:
    """Stops `link`'s arm and forgets the link (whoever handles a fault stops each arm
    once; the exit handler stops the links nobody stopped). Returns the error of the stop
    (None when it was confirmed) instead of raising, so that it can be reported beside the
    fault that caused it."""
    _open_links.discard(link)
    try:
        link.stop()
    except Exception as e:  # a dead link, a vendor RuntimeError: recorded, never raised
        return DescribeError(e)
    return None


def StopAllArms() -> list[str]:
    """Stops every open arm link; returns the errors, one line each, naming the link.
    Errors of one link do not keep the others running."""
    errors = ((link.name, StopArm(link)) for link in list(_open_links))
    return [f"{name}: {error}" for name, error in errors if error is not None]


def ReportStopErrors(errors: list[str], when: str) -> None:
    """Prints each error of stopping an arm, one line each, on stdout."""
    for error in errors:
        print(f"guidedarm: stopping an arm {when} failed: {error}", flush=True)


def FailStoppingAllArms(device: str, what: str, t: float) -> NoReturn:
    """A fault of a sensor (`device`) at diagram time t (s): stops every arm, then raises
    HardwareFaultError with the errors of the stops beside the cause."""
    stop_errors = StopAllArms()
    what = what if stop_errors else f"{what}; arms stopped"
    raise HardwareFaultError(device, what, t, stop_errors)


def _StopAllArmsAtExit() -> None:
    ReportStopErrors(StopAllArms(), "at exit")
    # The process is ending: keep the interpreter's final garbage collection away from the
    # many Drake objects it would walk (0.3 s, up to 1.3 s on a loaded 2-core machine), so
    # that a run ends promptly after a hardware fault. Nothing is left to finalize: the
    # summary is written and the arms are stopped.
    gc.freeze()


atexit.register(_StopAllArmsAtExit)
