"""Test doubles shared by the hardware tests: a recording control side for UR links, a
scripted ArmLink, and starting the loopback servers as separate processes."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np

from guidedarm.systems.hardware.arm_link import JointSample


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


def StartNachiEmulator(*args: str) -> tuple[subprocess.Popen, int, str]:
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
    process = subprocess.Popen([*command, *args], stdout=subprocess.PIPE, text=True)
    port = int(process.stdout.readline().split(":")[-1])
    device = process.stdout.readline().split()[-1]
    return process, port, device


def StopServer(process: subprocess.Popen) -> None:
    process.terminate()
    process.wait(timeout=5)


def Mz04dScenario(**fields):
    """The seed-000 cell (MZ04D, gripper, ToF tool) as a StationScenario."""
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
