"""What an arm driver needs from a robot link, whatever the vendor: the latest measured joint
sample (taken by the link's own I/O thread) and a way to command and to stop the arm.

Every open link is remembered so that a failure anywhere in a hardware diagram (a lost sensor,
Ctrl-C, an uncaught error at exit) can stop every arm: `StopAllArms`.
"""

from __future__ import annotations

import atexit
import threading
import time
import weakref
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from guidedarm.systems.errors import GuidedArmError


class LinkLostError(GuidedArmError):
    """A link (robot, sensor, camera) went quiet for longer than its watchdog period."""


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
    (rad) reached over `period` seconds; `stop` halts the arm and must be safe to repeat;
    `fault` is a one-line reason once the link can no longer be used, else None."""

    name: str

    def latest(self) -> JointSample | None: ...

    def fault(self) -> str | None: ...

    def send_position(self, q: np.ndarray, period: float) -> None: ...

    def stop(self) -> None: ...

    def close(self) -> None: ...


_open_links: weakref.WeakSet = weakref.WeakSet()


def RegisterArmLink(link: ArmLink) -> None:
    """Remembers `link` so that StopAllArms reaches it."""
    _open_links.add(link)


def StopAllArms() -> None:
    """Stops every open arm link; errors of one link do not keep the others running."""
    for link in list(_open_links):
        try:
            link.stop()
        except Exception as e:  # keep stopping the others; a dead link cannot move anyway
            print(f"guidedarm: stopping {link.name} failed: {e}", flush=True)


atexit.register(StopAllArms)
