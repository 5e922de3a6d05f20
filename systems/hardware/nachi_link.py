"""Nachi CFD controllers through the User Task line protocol, behind the ArmLink interface.

One I/O thread owns the socket: as soon as a joint target is pending (and at least every
`poll_period`) it sends the newest target (SET_TARGET + MOVE) and reads the joints
(READ_JOINTS). Velocities are differences of
successive joint readings over the controller's clock. Malformed reply lines are printed,
counted in `rejected_lines`, and skipped; the ArmDriver's watchdog covers a link that keeps
failing. A controller that refuses a target or a move (`NG ...`, e.g. after a STOP from its
pendant) or a lost connection is a fault: streaming ends and the ArmDriver fails the run.
Connecting sends RESET: starting a run is the deliberate act that clears an earlier STOP.
"""

from __future__ import annotations

import socket
import threading

import numpy as np

from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.arm_link import JointSample, LatestSample, RegisterArmLink
from guidedarm.systems.hardware.line_socket import LineSocket


class NachiLink:
    """ArmLink of a Nachi arm at (host, port)."""

    def __init__(
        self, name: str, host: str, port: int, poll_period: float = 0.002, timeout: float = 1.0
    ) -> None:
        self.name = name
        self.rejected_lines = 0
        self._fault: str | None = None
        try:
            connection = socket.create_connection((host, port), timeout=timeout)
        except OSError as e:
            raise nachi.NachiProtocolError(f"{name}: cannot reach {host}:{port}: {e}") from None
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._socket = LineSocket(connection, nachi.MAX_LINE)
        self._lock = threading.Lock()
        self._unanswered = False
        (reply,) = self.Request(nachi.RESET)
        nachi.CheckOk(reply)
        self._pending: np.ndarray | None = None
        self._poll_period = poll_period
        self._latest = LatestSample()
        self._previous: tuple[float, np.ndarray] | None = None
        self._closing = threading.Event()
        self._wake = threading.Event()
        self._thread = threading.Thread(target=self._Run, name=f"{name}-nachi", daemon=True)
        self._thread.start()
        RegisterArmLink(self)

    def Request(self, *lines: str) -> list[str]:
        """Sends request lines and returns their replies (thread-safe)."""
        with self._lock:
            if self._unanswered:
                self._socket.DiscardUnread()
                self._unanswered = False
            self._socket.WriteLines(*lines)
            try:
                return [self._socket.ReadLine() for _ in lines]
            except OSError:
                self._unanswered = True
                raise

    def _Run(self) -> None:
        while not self._closing.is_set():
            self._wake.wait(self._poll_period)
            self._wake.clear()
            target, self._pending = self._pending, None
            try:
                if target is not None:
                    for reply in self.Request(nachi.FormatSetTarget(target), nachi.MOVE):
                        nachi.CheckOk(reply)
                (reply,) = self.Request(nachi.READ_JOINTS)
                self._Check(self._Measured, reply)
            except nachi.NachiProtocolError as e:
                self._fault = str(e)
                return
            except OSError as e:
                self._fault = f"connection lost: {e}"
                return

    def _Check(self, parse, reply: str) -> None:
        try:
            parse(reply)
        except nachi.NachiProtocolError as e:
            self.rejected_lines += 1
            print(f"{self.name}: rejected reply #{self.rejected_lines}: {e}", flush=True)

    def _Measured(self, reply: str) -> None:
        t, q = nachi.ParseJoints(reply)
        if self._previous is not None and t <= self._previous[0]:
            return  # the controller has not produced a new sample yet
        v = (
            np.zeros_like(q)
            if self._previous is None
            else (q - self._previous[1]) / (t - self._previous[0])
        )
        self._previous = (t, q)
        self._latest.put(q, v)

    def latest(self) -> JointSample | None:
        return self._latest.get()

    def fault(self) -> str | None:
        return self._fault

    def send_position(self, q: np.ndarray, period: float) -> None:
        self._pending = np.array(q, float)
        self._wake.set()

    def stop(self) -> None:
        self._pending = None
        (reply,) = self.Request(nachi.STOP)
        nachi.CheckOk(reply)

    def close(self) -> None:
        self._closing.set()
        self._wake.set()
        self._thread.join(timeout=1.0)
        self._socket.connection.close()
