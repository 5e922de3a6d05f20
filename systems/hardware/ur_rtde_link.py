"""UR arms over RTDE (the `ur-rtde` package), behind the ArmLink interface.

The vendor API is reached through two small protocols of ours, so each side can be tested:
`RtdeReceive` (the subset of rtde_receive.RTDEReceiveInterface we use) is tested against a
loopback RTDE double speaking the wire protocol; `RtdeControl` (servoJ, servoStop of
rtde_control.RTDEControlInterface) against a recording fake. A poll thread copies each new
controller sample (a new RTDE `timestamp`) into LatestSample with the host time it arrived.
"""

from __future__ import annotations

import threading
from typing import Protocol

import numpy as np

from guidedarm.systems.hardware.arm_link import JointSample, LatestSample, RegisterArmLink

RTDE_FREQUENCY = 500.0  # Hz, e-Series controllers
SERVO_STOP_DECELERATION = 10.0  # rad/s^2, the vendor's default for servoStop


class RtdeReceive(Protocol):
    def getActualQ(self) -> list[float]: ...
    def getActualQd(self) -> list[float]: ...
    def getTimestamp(self) -> float: ...
    def isConnected(self) -> bool: ...
    def disconnect(self) -> None: ...


class RtdeControl(Protocol):
    def servoJ(
        self,
        q: list[float],
        speed: float,
        acceleration: float,
        time: float,
        lookahead_time: float,
        gain: float,
    ) -> bool: ...
    def servoStop(self, a: float) -> bool: ...
    def stopScript(self) -> None: ...


class UrRtdeLink:
    """ArmLink of a UR arm: servoJ streaming (lookahead_time s, gain 1/s as in URScript)."""

    def __init__(
        self,
        name: str,
        receive: RtdeReceive,
        control: RtdeControl,
        lookahead_time: float = 0.1,
        gain: float = 300.0,
        poll_period: float = 0.0005,
    ) -> None:
        self.name = name
        self._receive = receive
        self._control = control
        self._lookahead_time = lookahead_time
        self._gain = gain
        self._poll_period = poll_period
        self._latest = LatestSample()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Poll, name=f"{name}-rtde", daemon=True)
        self._thread.start()
        RegisterArmLink(self)

    def _Poll(self) -> None:
        last_timestamp = None
        while not self._closing.wait(self._poll_period):
            if not self._receive.isConnected():
                return
            timestamp = self._receive.getTimestamp()
            if timestamp != last_timestamp:
                last_timestamp = timestamp
                self._latest.put(self._receive.getActualQ(), self._receive.getActualQd())

    def latest(self) -> JointSample | None:
        return self._latest.get()

    def fault(self) -> str | None:
        return None if self._receive.isConnected() else "RTDE connection lost"

    def send_position(self, q: np.ndarray, period: float) -> None:
        self._control.servoJ(
            [float(x) for x in q], 0.0, 0.0, period, self._lookahead_time, self._gain
        )

    def stop(self) -> None:
        self._control.servoStop(SERVO_STOP_DECELERATION)

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=1.0)
        self._receive.disconnect()
        self._control.stopScript()


def OpenUrRtde(name: str, host: str, lookahead_time: float, gain: float) -> UrRtdeLink:
    """Connects both vendor interfaces to the controller at `host` (RTDE port 30004)."""
    import rtde_control
    import rtde_receive

    variables = ["timestamp", "actual_q", "actual_qd"]
    receive = rtde_receive.RTDEReceiveInterface(host, RTDE_FREQUENCY, variables)
    control = rtde_control.RTDEControlInterface(host, RTDE_FREQUENCY)
    return UrRtdeLink(name, receive, control, lookahead_time, gain)
