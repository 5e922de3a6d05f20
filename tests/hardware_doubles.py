"""Test doubles shared by the hardware tests: a recording control side for UR links, a
scripted ArmLink, a Nachi controller that can freeze, a relay that silences or garbles a ToF
stream between two pseudo-terminals, and starting the loopback servers as separate
processes."""

from __future__ import annotations

import contextlib
import os
import select
import socket
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable

import numpy as np

from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.arm_link import JointSample
from guidedarm.systems.hardware.line_socket import LineSocket
from guidedarm.systems.hardware.nachi_emulator import NachiControllerLogic

# s; how long a test waits for something that must happen: a bound for a loaded machine,
# not a timing (the tests' verdicts never depend on how long it takes within it).
LOADED_MACHINE_BOUND = 5.0
# s; the Nachi emulator's streaming timeout in tests that are not about it: the default
# 0.1 s ran out when the shared CPU delayed a client in the same process (NG E07).
RELAXED_SERVO_TIMEOUT = 2.0


def WaitUntil(condition: Callable[[], bool], timeout: float = LOADED_MACHINE_BOUND) -> bool:
    """Polls `condition` every millisecond until it holds or `timeout` s passed; returns it."""
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.001)
    return condition()


class RecordingRtdeControl:
    """Records the calls the RtdeControl protocol allows, with their host times."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple, float]] = []

    def servoJ(self, q, speed, acceleration, time_, lookahead_time, gain) -> bool:
        self.calls.append(("servoJ", (list(q), time_, lookahead_time, gain), time.monotonic()))
        return True

    def servoStop(self, a: float) -> bool:
        self.calls.append(("servoStop", (a,), time.monotonic()))
        return True

    def setWatchdog(self, min_frequency: float) -> bool:
        self.calls.append(("setWatchdog", (min_frequency,), time.monotonic()))
        return True

    def kickWatchdog(self) -> bool:
        self.calls.append(("kickWatchdog", (), time.monotonic()))
        return True

    def stopScript(self) -> None:
        self.calls.append(("stopScript", (), time.monotonic()))

    def Count(self, name: str) -> int:
        return sum(1 for call in self.calls if call[0] == name)


class ScriptedArmLink:
    """An ArmLink whose measurement the test sets (q, v and its age in seconds)."""

    name = "scripted"

    def __init__(self, q: np.ndarray) -> None:
        self.q = np.asarray(q, float)
        self.age = 0.0
        self.sent: list[np.ndarray] = []
        self.stops = 0

    def latest(self) -> JointSample:
        return JointSample(self.q, np.zeros_like(self.q), time.monotonic() - self.age)

    def fault(self) -> str | None:
        return None

    def send_position(self, q: np.ndarray, period: float) -> None:
        self.sent.append(np.array(q))

    def stop(self) -> None:
        self.stops += 1

    def close(self) -> None:
        pass


class FreezingNachiController:
    """A Nachi controller on 127.0.0.1 (NachiControllerLogic, the arm exactly where it is
    commanded, the controller clock the host's) that can `freeze`: from then on it receives
    and records request lines with their arrival times but answers none, as a controller
    whose task hangs while its TCP stack still accepts bytes; it freezes by itself after
    answering `answers` lines. `measurement_offset` corrupts the joints it reports (its sign
    flipping at every READ_JOINTS with `flip_offset`: a reading that jumps back and forth).
    `clock_step` (s): the controller clock advances this much per request answered instead
    of following the host's, so that velocities between its readings do not depend on how
    the OS schedules the threads."""

    def __init__(
        self, q0: np.ndarray, answers: float = np.inf, clock_step: float | None = None
    ) -> None:
        self.logic = NachiControllerLogic(
            np.full(6, -np.pi), np.full(6, np.pi), q0, servo_timeout=RELAXED_SERVO_TIMEOUT
        )
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self.frozen = False
        self._answers = answers
        self.measurement_offset = np.zeros(6)  # rad, added to the joints it reports
        self.flip_offset = False
        # host time (time.monotonic(), s) the last joint measurement (a READ_JOINTS reply) was sent
        self.last_measurement = 0.0
        self.received_frozen: list[tuple[float, str]] = []
        self._clock_step = clock_step
        threading.Thread(target=self._Serve, daemon=True).start()

    def _Serve(self) -> None:
        connection, _ = self._server.accept()
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        lines = LineSocket(connection)
        start = time.monotonic()
        answered = 0
        with connection, contextlib.suppress(OSError):
            while True:
                line = lines.ReadLine()
                self.frozen = self.frozen or self._answers <= 0
                self._answers -= 1
                if self.frozen:
                    self.received_frozen.append((time.monotonic(), line))
                    continue
                q = self.logic.commanded
                answered += 1
                t = time.monotonic() - start if self._clock_step is None else 0.0
                t += answered * (self._clock_step or 0.0)
                self.logic.Measure(t, q, np.zeros(3), np.zeros(3))
                if self.flip_offset and line == nachi.READ_JOINTS:
                    self.measurement_offset = -self.measurement_offset
                self.logic.measured = q + self.measurement_offset
                replies = self.logic.Handle(line)
                # The driver's watchdog runs from its newest measurement: the reply to a
                # target (OK) refreshes nothing. Stamped before the write, which the link
                # may read and stamp before this thread runs again.
                if line == nachi.READ_JOINTS:
                    self.last_measurement = time.monotonic()
                lines.WriteLines(replies)

    def close(self) -> None:
        with contextlib.suppress(OSError):  # wakes an accept() that no client reached
            self._server.shutdown(socket.SHUT_RDWR)
        self._server.close()


def StartServer(module: str, *args: str, stderr=None) -> tuple[subprocess.Popen, int]:
    """Runs `python -m module args` and waits for its `listening HOST PORT` line."""
    process = subprocess.Popen(
        [sys.executable, "-m", module, *args], stdout=subprocess.PIPE, stderr=stderr, text=True
    )
    line = process.stdout.readline().split()
    if not line or line[0] != "listening":
        process.kill()
        raise RuntimeError(f"{module} did not start: {line}")
    return process, int(line[2])


def StartNachiEmulator(*args: str, stderr=None) -> tuple[subprocess.Popen, int, str]:
    """Runs `guidedarm emulate nachi --port 0 args`: (process, TCP port, ToF pty device)."""
    command = [
        sys.executable,
        "-m",
        "guidedarm.diagrams.cli.main",
        "emulate",
        "nachi",
        "--port",
        "0",
    ]
    process = subprocess.Popen([*command, *args], stdout=subprocess.PIPE, stderr=stderr, text=True)
    port = int(process.stdout.readline().split(":")[-1])
    device = process.stdout.readline().split()[-1]
    return process, port, device


class ToFRelay:
    """Copies the bytes of a ToF stream from `source` (a pty device) to a new pseudo-terminal,
    `device`, until `mode` says otherwise: "forward", "silent" (the tool goes quiet: bytes are
    dropped) or "garbage" (each chunk is replaced by binary noise and malformed lines)."""

    GARBAGE = (
        b"\x00\xff\xfe$TOF,1,\xc3\xa9,0*00\r\n",
        b"$TOF,7,10,0,10,0,10,0,10,0,10,0,10,0*FF\r\n",  # checksum mismatch
        bytes(range(256)) + b"\n",
        b"x" * 300 + b"\r\n",
    )

    def __init__(self, source: str) -> None:
        self._source = os.open(source, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.device = os.ttyname(self._slave)
        os.set_blocking(self._master, False)  # drop bytes while nobody reads the device
        self.mode = "forward"
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Run, name="tof-relay", daemon=True)
        self._thread.start()

    def _Run(self) -> None:
        garbage = 0
        while not self._closing.is_set():
            if not select.select([self._source], [], [], 0.05)[0]:
                continue
            try:
                chunk = os.read(self._source, 4096)
            except BlockingIOError:
                continue
            if self.mode == "garbage":
                chunk, garbage = self.GARBAGE[garbage % len(self.GARBAGE)], garbage + 1
            if self.mode != "silent":
                with contextlib.suppress(BlockingIOError):
                    os.write(self._master, chunk)

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=1.0)
        for fd in (self._source, self._master, self._slave):
            os.close(fd)


def StopServer(process: subprocess.Popen) -> None:
    process.terminate()
    process.wait(timeout=5)


def Mz04dScenario(**fields):
    """The Wawrzyniak et al. cell (MZ04D, gripper, ToF tool) as a StationScenario."""
    from pydrake.multibody.parsing import LoadModelDirectives

    from guidedarm.diagrams.station.model_paths import MODELS_DIR
    from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario

    directives = LoadModelDirectives(str(MODELS_DIR / "directives/mz04d_cell.dmd.yaml"))
    return StationScenario(directives=directives.directives, arms={"mz04d": ArmConfig()}, **fields)


def WriteTestVideo(path, width: int, height: int, fps: float, frames: int) -> list:
    """A video whose frame k is filled with the colour COLOURS[k % len] (BGR)."""
    import cv2

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (width, height))
    for k in range(frames):
        writer.write(np.full((height, width, 3), VIDEO_COLOURS_BGR[k % 3], np.uint8))
    writer.release()
    return VIDEO_COLOURS_BGR


VIDEO_COLOURS_BGR = [(255, 0, 0), (0, 255, 0), (0, 0, 255)]


MZ04D_HOME = "[0.0, 1.5707963267948966, 0.0, 0.0, -1.5707963267948966, 0.0]"


def Mz04dCalibrationCell(directives: str, cameras: str = "", camera_drivers: str = "") -> str:
    """The text of a joint_tour scenario of the MZ04D cell (gripper, ToF tool `tof`, no hose;
    its station the scenario's own, so it may have drivers): the arm at home with a 10 ms
    control period on a `!NachiDriver`, the tool on a `!ToFSerialDriver`, `directives`
    (YAML list items, 2-space indent) added to the cell's, and `cameras` and
    `camera_drivers` (YAML mapping items, 4-space indent) when given."""
    camera_section = f"  cameras:\n{cameras}" if cameras else ""
    camera_driver_section = f"    cameras:\n{camera_drivers}" if camera_drivers else ""
    return f"""task: joint_tour
arm: mz04d
waypoints: [{MZ04D_HOME}]
station:
  directives:
  - add_directives: {{file: package://guidedarm/directives/mz04d_cell.dmd.yaml}}
{directives}  arms:
    mz04d: {{initial_position: {MZ04D_HOME}, control_period: 0.01}}
{camera_section}  tof_tools:
    tof: {{}}
  hardware:
    arms:
      mz04d: !NachiDriver {{acceleration_limits: [10, 10, 10, 10, 10, 10]}}
{camera_driver_section}    tof_tools:
      tof: !ToFSerialDriver {{device: /dev/rfcomm0}}
"""
