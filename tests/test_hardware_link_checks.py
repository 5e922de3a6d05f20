"""Before any motion every link of a hardware run proves itself or the run is refused in one
line naming it (exit 2, no summary); hardware entries for devices the scenario does not have
are refused; a controller that refuses the stream after stale measurements names the
setting to change."""

from __future__ import annotations

import ipaddress
import os
import random
import re
import subprocess
import sys
import time
import tty

import numpy as np
import pytest
from hardware_doubles import Mz04dScenario, ScriptedArmLink, StartServer, WriteTestVideo
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.station.hardware_config import (
    HardwareConfig,
    NachiDriver,
    OpenCvCameraDriver,
)
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.hardware.nachi_protocol import CheckOk, NachiProtocolError
from guidedarm.systems.hardware.tof_emulator import ToFEmulator

CLI = [sys.executable, "-m", "guidedarm.diagrams.cli.main"]


def FreeLoopbackHost() -> str:
    """A loopback address (127.0.0.0/8) other than 127.0.0.1, for servers on fixed ports."""
    return str(ipaddress.IPv4Address("127.0.0.0") + random.randrange(2, 2**24 - 2))


def _Refused(*args: str, timeout: float = 60.0) -> str:
    """Runs the command, expects a one-line refusal (exit 2); returns the line."""
    result = subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = [line for line in result.stderr.splitlines() if line.startswith("guidedarm:")]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def test_an_idle_tof_device_is_refused_before_any_arm_connects(tmp_path):
    """A pty that exists and sends nothing: refused naming the tool and its device, before
    the arm (nothing listens on its port) is even reached."""
    master, slave = os.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    try:
        line = _Refused(
            "run", "path_following", "--hardware", "--out", str(tmp_path / "run"),
            "--set", f"station.hardware.tof_tools.tof.device={device}",
            "--set", "station.hardware.arms.mz04d.port=1",
        )  # fmt: skip
    finally:
        os.close(master)
        os.close(slave)
    assert line == (
        f"guidedarm: error: tof: {device} opened, but no valid line within 2.0 s (0 lines "
        "rejected): is the tool powered and streaming on that device?"
    )
    assert not (tmp_path / "run" / "summary.json").exists()


@pytest.mark.parametrize(
    "entry, message",
    [
        (
            "station.hardware.arms.ur10e=!UrRtdeDriver {host: 127.0.0.9}",
            "hardware.arms.ur10e: the scenario has no such arm (its arms: ['mz04d']); remove "
            "the entry",
        ),
        (
            "station.hardware.tof_tools.tof2={device: /dev/ttyUSB7}",
            "hardware.tof_tools.tof2: the scenario has no such tof tool (its tof_tools: "
            "['tof']); remove the entry",
        ),
    ],
)
def test_a_hardware_entry_for_a_device_the_scenario_lacks_is_refused(entry, message, tmp_path):
    line = _Refused(
        "run", "path_following", "--hardware", "--out", str(tmp_path / "run"), "--set", entry
    )
    assert line == f"guidedarm: error: {message}"


def test_ur_rtde_against_an_rtde_only_server_is_refused_within_its_deadline(tmp_path):
    """The repo's RTDE stand-in serves data packages on 30004 only: the vendor control
    interface waited 120 s on it; the probe refuses it at once, naming the port."""
    host = FreeLoopbackHost()
    server, _ = StartServer("guidedarm.systems.hardware.rtde_double", "--host", host)
    try:
        start = time.monotonic()
        line = _Refused(
            "run", "ur10e_joint_tour", "--hardware", "--out", str(tmp_path / "run"),
            "--set", f"station.hardware.arms.ur10e.host={host}",
        )  # fmt: skip
    finally:
        server.kill()
        server.wait()
    assert line == (
        f"guidedarm: error: ur10e: cannot connect to the UR controller at {host}: dashboard "
        f"server {host}:29999: [Errno 111] Connection refused"
    )
    assert time.monotonic() - start < 60.0  # the command's start-up; the probe takes ms


class RefusingLink(ScriptedArmLink):
    """A link whose measurements are `stale_age` old (older than stale_after, within the
    watchdog) until `fresh_after` updates, and whose controller refuses the stream after
    `refuse_after` updates (as a real one does on the first target after a pause)."""

    name = "mz04d"

    def __init__(self, q, stale_age: float, fresh_after: int, refuse_after: int) -> None:
        super().__init__(q)
        self.updates = 0
        self.stale_age, self.fresh_after, self.refuse_after = stale_age, fresh_after, refuse_after

    def fault(self) -> str | None:
        self.updates += 1
        self.age = self.stale_age if self.updates <= self.fresh_after else 0.0
        if self.updates > self.refuse_after:
            return "controller refused: 'NG E07 servo timeout; send RESET before SERVO'"
        return None


def _Limits(n: int = 6) -> JointLimits:
    return JointLimits(
        [f"joint{i + 1}" for i in range(n)],
        np.full(n, -3.0),
        np.full(n, 3.0),
        np.full(n, 2.0),
        np.full(n, 10.0),
    )


@pytest.mark.parametrize(
    "stale_age, fresh_after, hint",
    [(0.03, 100, True), (0.03, 10, True), (0.0, 100, False)],
    ids=["stale until refused", "refused at the first target after the streak", "fresh"],
)
def test_a_stream_refused_after_stale_measurements_names_the_setting(stale_age, fresh_after, hint):
    # stale_after 0.02 s, watchdog 0.1 s
    link = RefusingLink(np.zeros(6), stale_age, fresh_after, refuse_after=12)
    builder = DiagramBuilder()
    driver = builder.AddSystem(ArmDriver(link, _Limits(), 0.01, watchdog=0.1, stale_after=0.02))
    source = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
    builder.Connect(source.get_output_port(), driver.get_input_port())
    simulator = Simulator(builder.Build())
    with pytest.raises(HardwareFaultError) as fault:
        simulator.AdvanceTo(1.0)
    text = str(fault.value)
    assert "NG E07 servo timeout" in text
    setting = "raise station.hardware.arms.mz04d.stale_after, at most the watchdog 0.1 s"
    assert (setting in text) == hint
    if hint:  # every update skipped its command until the measurements were fresh
        periods = int(re.search(r"no command sent for (\d+) periods", text)[1])
        assert periods == min(round(fault.value.t / 0.01), fresh_after)
    assert link.stops == 1


def test_a_camera_with_frames_of_another_size_is_refused_before_any_arm_connects(tmp_path):
    """A 64 x 48 video for a 640 x 480 camera: refused naming the camera and both sizes,
    before the arm (nothing listens on its port) is reached."""
    video = tmp_path / "camera.avi"
    WriteTestVideo(video, 64, 48, 30.0, 10)
    hardware = HardwareConfig(
        arms={"mz04d": NachiDriver(port=1, acceleration_limits=[10] * 6)},
        cameras={"camera": OpenCvCameraDriver(source=str(video))},
    )
    scenario = Mz04dScenario(cameras={"camera": CameraConfig(width=640, height=480)})
    scenario.hardware = hardware
    with pytest.raises(ConfigurationError) as refusal:
        MakeStation(scenario, kind="hardware")
    assert str(refusal.value) == (
        f"camera: camera '{video}' delivers 64x48 frames, the scenario expects 640x480"
    )


def test_an_unread_tof_pty_drops_lines_instead_of_stalling_the_emulator():
    """An emulator's ToF pty that nobody reads (the run pointed at another device) fills in
    seconds; its writes must not block, or the simulation thread that writes them, and with
    it the emulated arm, freezes and the run blames the arm ("link quiet")."""
    tof = ToFEmulator(None)
    try:
        start = time.monotonic()
        for _ in range(5000):  # about 300 kB, far beyond a pty's buffer
            assert tof.Write(np.full(6, 0.05), np.zeros(6, int))
        elapsed = time.monotonic() - start
    finally:
        tof.close()
    assert tof.dropped > 0
    assert tof.lines == 5000
    print(f"\n5000 lines written in {elapsed:.3f} s, {tof.dropped} dropped")


def test_a_streaming_timeout_names_the_controller_setting():
    with pytest.raises(NachiProtocolError) as refusal:
        CheckOk("NG E07 servo timeout; send RESET before SERVO")
    assert str(refusal.value).endswith(
        "(no SERVO reached the controller within its streaming timeout, a User Task "
        "setting; `guidedarm emulate nachi --servo-timeout`)"
    )
    with pytest.raises(NachiProtocolError) as other:
        CheckOk("NG E05 stopped; send RESET before SERVO")
    assert str(other.value) == "controller refused: 'NG E05 stopped; send RESET before SERVO'"
