"""UR arms over RTDE (the `ur-rtde` package), behind the ArmLink interface.

The vendor API is reached through two small protocols of ours, so each side can be tested:
`RtdeReceive` (the subset of rtde_receive.RTDEReceiveInterface we use) is tested against a
loopback RTDE double speaking the wire protocol; `RtdeControl` (servoJ, servoStop of
rtde_control.RTDEControlInterface) against a recording fake. A station's link reaches the
vendor interfaces in a process of their own (ur_rtde_process: the library can crash when a
connection drops, and the run must still stop and report). A poll thread copies each new
controller sample (a later RTDE `timestamp`) into LatestSample with the host time it arrived;
an error of the vendor interface in that thread is the link's fault. A servoJ or servoStop
the controller does not accept raises, so the ArmDriver stops the arm and fails the run.
The control script's watchdog is the streaming timeout, as the Nachi controller's: set to
1 / `servo_timeout` Hz and fed by every servoJ (it watches input_int_register_0, which
each servoJ writes), so a PC that stops streaming (dead,
frozen, cut off) has the controller stop the robot by itself.

Connecting is part of building the station, before any motion: a controller that cannot
be reached is a ConfigurationError (one line, naming the host and the vendor's message).
The vendor constructors have no deadline of their own (against a server that accepts the
connection and never answers they wait for minutes, holding the GIL), so `ProbeUrController`
first checks, each within `connect_timeout`, every port they use (ur_rtde hard-codes them):
RTDE 30004 answers the protocol version and controller version requests, the dashboard
server 29999 sends its welcome line and answers `PolyscopeVersion`, the script port 30003
accepts a connection.
"""

from __future__ import annotations

import contextlib
import math
import socket
import struct
import threading
import time
from typing import Protocol

import numpy as np

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import rtde_protocol as rtde
from guidedarm.systems.hardware.arm_link import (
    DescribeError,
    JointSample,
    LatestSample,
    RegisterArmLink,
    RegisterVendorThread,
    UnregisterArmLink,
)
from guidedarm.systems.hardware.ur_rtde_process import UrRtdeClientProcess

RTDE_FREQUENCY = 500.0  # Hz, e-Series controllers
# The controller ports ur_rtde 1.6.5 connects to (fixed in the library).
RTDE_PORT = 30004
DASHBOARD_PORT = 29999
SCRIPT_PORT = 30003
CONNECT_TIMEOUT = 2.0  # s, for each port of ProbeUrController
LOCKSTEP_REGISTER = 18  # output_int_register_18: servoJ run by `emulate ur --lockstep`
RUNTIME_PLAYING = 2  # RTDE runtime_state of a running program
CLOSE_TIMEOUT = 1.0  # s, for disconnecting both vendor interfaces
SERVO_STOP_DECELERATION = 10.0  # rad/s^2, the vendor's default for servoStop


class RtdeReceive(Protocol):
    def getActualQ(self) -> list[float]: ...
    def getActualQd(self) -> list[float]: ...
    def getTimestamp(self) -> float: ...
    def getRuntimeState(self) -> int: ...
    def getOutputIntRegister(self, output_id: int) -> int: ...
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
    def setWatchdog(self, min_frequency: float) -> bool: ...
    def kickWatchdog(self) -> bool: ...
    def stopScript(self) -> None: ...


class UrRtdeLink:
    """ArmLink of a UR arm: servoJ streaming (lookahead_time s, gain 1/s as in URScript),
    the controller stopping the robot when no servoJ came for `servo_timeout` s."""

    def __init__(
        self,
        name: str,
        receive: RtdeReceive,
        control: RtdeControl,
        lookahead_time: float = 0.1,
        gain: float = 300.0,
        poll_period: float = 0.0005,
        servo_timeout: float = 0.1,
        stop_timeout: float = 0.25,
        lockstep_wait: float | None = None,
    ) -> None:
        if not control.setWatchdog(1.0 / servo_timeout):
            raise ConfigurationError(f"{name}: the UR controller refused its watchdog")
        self.name = name
        self._receive = receive
        self._control = control
        self._lookahead_time = lookahead_time
        self._gain = gain
        self._poll_period = poll_period
        self._stop_timeout = stop_timeout
        self._servo_timeout = servo_timeout
        self._command_lock = threading.Lock()  # orders the kicks before the first servoJ
        self._streaming = False
        # lockstep (an emulator whose clock the servoJ stream sets): `latest` waits at most
        # this long for a sample received after the last servoJ was sent.
        self._lockstep_wait = lockstep_wait
        self._sample_arrived = threading.Condition()
        # servoJ sent and run by the emulator (mod 2^31, as of the newest sample), counted
        # from the emulator's count at the first sample (it counts over all its clients).
        self._sent: int | None = None
        self._run = 0
        self._fault: str | None = None
        self._latest = LatestSample()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Poll, name=f"{name}-rtde", daemon=True)
        RegisterVendorThread(self._thread)
        self._thread.start()
        RegisterArmLink(self)

    def _Poll(self) -> None:
        last_timestamp = -math.inf
        last_kick = time.monotonic()
        try:
            while not self._closing.wait(self._poll_period):
                if time.monotonic() - last_kick > self._servo_timeout / 4:
                    last_kick = time.monotonic()
                    self._KickUntilStreaming()
                if not self._receive.isConnected():
                    self._fault = "RTDE connection lost"
                    return
                timestamp = self._receive.getTimestamp()
                # Only a later controller time is a new sample: a timestamp that repeats,
                # runs backwards or is not a number (NaN != NaN) comes with stale data.
                if timestamp > last_timestamp:
                    last_timestamp = timestamp
                    q, v = self._receive.getActualQ(), self._receive.getActualQd()
                    with self._sample_arrived:
                        if self._lockstep_wait is not None:
                            self._run = self._receive.getOutputIntRegister(LOCKSTEP_REGISTER)
                            self._sent = self._run if self._sent is None else self._sent
                        self._latest.put(q, v)
                        self._sample_arrived.notify_all()
        except Exception as e:  # the vendor raises RuntimeError; any error ends the stream
            self._fault = f"RTDE receive failed: {DescribeError(e)}"

    def _KickUntilStreaming(self) -> None:
        """Feeds the control script's watchdog between connecting and the first servoJ
        (building the diagram takes longer than the streaming timeout); never once the
        stream has begun: then a stream that stops must let the controller stop the arm."""
        with self._command_lock:
            if not self._streaming:
                self._control.kickWatchdog()

    def latest(self) -> JointSample | None:
        """The newest sample; in lockstep, one the emulator published after running every
        servoJ sent (its count in output_int_register_18; waiting at most lockstep_wait),
        stamped now: the emulator's clock is the stream's, its age on the host says nothing."""
        if self._lockstep_wait is None:
            return self._latest.get()
        with self._sample_arrived:
            arrived = self._sample_arrived.wait_for(self._SampleAfterLastSend, self._lockstep_wait)
        sample = self._latest.get()
        if not arrived or sample is None or self._fault is not None:
            return sample
        # Fresh by construction (it follows every target sent), however long the host took.
        return JointSample(sample.q, sample.v, time.monotonic())

    def _SampleAfterLastSend(self) -> bool:
        return self._fault is not None or (self._sent is not None and self._run == self._sent)

    def fault(self) -> str | None:
        return self._fault

    def send_position(self, q: np.ndarray, period: float) -> None:
        q = [float(x) for x in q]
        # No kickWatchdog after it: each servoJ writes input_int_register_0, which is what
        # the watchdog watches, and a kick (NO_CMD in that register) sent right after could
        # overwrite the servoJ before the control script's next cycle reads it.
        with self._command_lock:
            self._streaming = True
            accepted = self._control.servoJ(q, 0.0, 0.0, period, self._lookahead_time, self._gain)
        if not accepted:
            if self._ProgramStopped():
                raise RuntimeError(
                    "servoJ not accepted: the control program has stopped (its watchdog: no "
                    "servoJ within servo_timeout, or a stop from the pendant or dashboard)"
                )
            raise RuntimeError("servoJ not accepted by the controller")
        with self._sample_arrived:
            if self._sent is not None:
                self._sent = (self._sent + 1) % 2**31

    def stop(self) -> None:
        """servoStop, confirmed by the controller within `stop_timeout` s: the vendor call
        waits up to 300 s for a controller that stopped answering (it releases the GIL,
        so it waits in a thread of its own, left behind if it does not return)."""

        def servo_stop() -> bool:
            with self._command_lock:  # the vendor interface is not safe across threads
                return self._control.servoStop(SERVO_STOP_DECELERATION)

        stopped = _CallWithin(servo_stop, self._stop_timeout)
        if stopped is None:
            raise TimeoutError(f"servoStop unconfirmed within {self._stop_timeout} s")
        # The client refuses every command once the program has stopped (its watchdog,
        # a stop from the pendant or the dashboard): the controller stopped the arm then.
        if not stopped and not self._ProgramStopped():
            raise RuntimeError("servoStop not accepted by the controller")

    def _ProgramStopped(self) -> bool:
        """Whether the program has stopped, waiting up to stop_timeout s for the RTDE sample
        that says so (a command refused because it stopped can come before that sample)."""
        deadline = time.monotonic() + self._stop_timeout
        while self._receive.getRuntimeState() == RUNTIME_PLAYING:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.002)
        return True

    def close(self) -> None:
        """Ends the poll thread, then disconnects and ends the control script and drops both
        vendor interfaces (their destructors run here, not in the interpreter's teardown),
        giving the vendor calls (each of which can wait minutes on a dead controller)
        CLOSE_TIMEOUT s together. A call still running then is left behind
        (VendorThreadsAlive)."""
        self._closing.set()
        UnregisterArmLink(self)

        def release() -> None:
            # The poll thread's receive calls must end before the interface is disconnected.
            self._thread.join()
            with contextlib.suppress(Exception):  # closing a dead vendor interface
                self._receive.disconnect()
            with self._command_lock, contextlib.suppress(Exception):
                self._control.stopScript()
            self._receive = self._control = None

        _CallWithin(release, CLOSE_TIMEOUT)


def _CallWithin(call, timeout: float):
    """call()'s result if it returns within `timeout` s, else None (the call goes on in its
    daemon thread); an exception it raises is raised here."""
    result: list = []

    def run() -> None:
        try:
            result.append((call(), None))
        except Exception as e:  # handed to the caller
            result.append((None, e))

    thread = threading.Thread(target=run, name="ur-rtde-call", daemon=True)
    RegisterVendorThread(thread)
    thread.start()
    thread.join(timeout)
    if not result:
        return None
    value, error = result[0]
    if error is not None:
        raise error
    return value


def _ReadExactly(connection: socket.socket, size: int) -> bytes:
    data = b""
    while len(data) < size:
        chunk = connection.recv(size - len(data))
        if not chunk:
            raise ConnectionError("the controller closed the connection")
        data += chunk
    return data


def _RtdeRequest(connection: socket.socket, packet_type: int, payload: bytes) -> bytes:
    """Sends one RTDE request and returns the payload of its reply (same type)."""
    connection.sendall(rtde.EncodePacket(packet_type, payload))
    while True:
        size, reply_type = rtde.HEADER.unpack(_ReadExactly(connection, rtde.HEADER.size))
        body = _ReadExactly(connection, max(0, size - rtde.HEADER.size))
        if reply_type == packet_type:
            return body


def _ProbeRtde(connection: socket.socket) -> str:
    accepted = _RtdeRequest(
        connection, rtde.REQUEST_PROTOCOL_VERSION, struct.pack(">H", rtde.PROTOCOL_VERSION)
    )
    if accepted[:1] != b"\x01":
        raise ConnectionError(f"RTDE protocol version {rtde.PROTOCOL_VERSION} refused")
    version = struct.unpack(">IIII", _RtdeRequest(connection, rtde.GET_URCONTROL_VERSION, b""))
    return ".".join(map(str, version))


def _ProbeDashboard(connection: socket.socket) -> str:
    reader = connection.makefile("rb")
    reader.readline()  # the welcome line
    connection.sendall(b"PolyscopeVersion\n")
    return reader.readline().decode("ascii", "replace").strip()


def ProbeUrController(host: str, timeout: float = CONNECT_TIMEOUT) -> dict[str, str]:
    """Checks, each within `timeout` s, that the ports ur_rtde uses at `host` answer (see
    the module docstring); returns what they said, or raises ConnectionError naming the
    port that did not."""
    said = {}
    probes = (
        ("RTDE", RTDE_PORT, _ProbeRtde),
        ("dashboard server", DASHBOARD_PORT, _ProbeDashboard),
        ("script port", SCRIPT_PORT, None),
    )
    for what, port, probe in probes:
        try:
            with socket.create_connection((host, port), timeout=timeout) as connection:
                said[what] = probe(connection) if probe else "open"
        except TimeoutError:
            raise ConnectionError(f"{what} {host}:{port}: no answer within {timeout} s") from None
        except (OSError, struct.error, ValueError) as e:  # a timeout is an OSError
            raise ConnectionError(f"{what} {host}:{port}: {DescribeError(e)}") from None
    return said


def OpenUrRtde(
    name: str,
    host: str,
    lookahead_time: float,
    gain: float,
    servo_timeout: float,
    lockstep_wait: float | None = None,
) -> UrRtdeLink:
    """Connects both vendor interfaces to the controller at `host` (RTDE port 30004), after
    ProbeUrController, in a process of their own (UrRtdeClientProcess)."""
    register = LOCKSTEP_REGISTER if lockstep_wait is not None else None
    try:
        ProbeUrController(host)
        client = UrRtdeClientProcess(host, RTDE_FREQUENCY, register)
    except ConnectionError as e:
        raise ConfigurationError(
            f"{name}: cannot connect to the UR controller at {host}: {e}"
        ) from None
    receive, control = client.receive, client.control
    return UrRtdeLink(
        name,
        receive,
        control,
        lookahead_time,
        gain,
        servo_timeout=servo_timeout,
        lockstep_wait=lockstep_wait,
    )
