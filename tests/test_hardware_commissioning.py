"""Bringing a cell up as docs/hardware.md tells an integrator: `guidedarm hardware-check`
reads every link and commands nothing, `guidedarm move-to-start` brings the arm to the
task's start pose at reduced speed, then the run starts from there."""

from __future__ import annotations

import re
import socket
import subprocess
import sys

import numpy as np
import pytest
from hardware_doubles import StartNachiEmulator, StopServer
from test_hardware_ur_emulator import UrCell

from guidedarm.diagrams.station.move_to_start import MoveDuration, MoveTrajectory
from guidedarm.systems.hardware.command_guard import JointLimits

CLI = [sys.executable, "-m", "guidedarm.diagrams.cli.main"]
TOUR = "ur10e_joint_tour"
# The tour's start (its scenario's initial position) with joint 1 0.1 rad further.
AWAY = "[-1.4708, -1.5708, -2.356194, -0.785398, 1.5708, 0.785398]"


def _Guidedarm(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=180)


@pytest.mark.parametrize("speed_scale", [0.1, 0.5])
def test_the_move_stays_within_the_scaled_limits(speed_scale):
    limits = JointLimits(
        [f"j{i}" for i in range(3)], -np.ones(3) * 6, np.ones(3) * 6, np.array([2.0, 2.0, 3.0]),
        np.array([5.0, 10.0, 10.0]),
    )  # fmt: skip
    for q_to in ([0.1, 0.0, 0.0], [1.0, -2.0, 0.5], [1e-4, 0.0, 0.0]):
        duration = MoveDuration(np.zeros(3), np.array(q_to), limits, speed_scale)
        trajectory = MoveTrajectory(np.zeros(3), np.array(q_to), duration)
        t = np.linspace(0.0, duration, 2001)
        v = np.column_stack([trajectory.EvalDerivative(s, 1) for s in t])
        a = np.column_stack([trajectory.EvalDerivative(s, 2) for s in t])
        assert np.all(np.abs(v).max(axis=1) <= speed_scale * limits.velocity + 1e-9)
        assert np.all(np.abs(a).max(axis=1) <= speed_scale * limits.acceleration + 1e-9)
        np.testing.assert_allclose(trajectory.value(duration).ravel(), q_to, atol=1e-12)


@pytest.mark.parametrize(
    "args, message",
    [
        ((TOUR,), "move-to-start drives the real arms: add --hardware"),
        ((TOUR, "--hardware", "--speed-scale", "2"), "--speed-scale 2.0: must be in (0, 1]"),
    ],
)
def test_move_to_start_refusals(args, message):
    result = _Guidedarm("move-to-start", *args)
    assert result.returncode == 2
    assert result.stderr.strip() == f"guidedarm: error: {message}"


def _NachiStatus(port: int) -> str:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as connection:
        connection.sendall(b"STATUS\n")
        return connection.makefile("r").readline().strip()


def test_hardware_check_reads_the_mz04d_cell_and_commands_nothing():
    """The emulated MZ04D cell (arm at the run's start pose, ToF tool on a pty): the check
    reports the joints at the start pose and the six ranges in order r1..r6, and leaves the
    controller as it found it (no RESET, no STOP, no target)."""
    emulator, port, device = StartNachiEmulator("--scenario", "path_following")
    try:
        before = _NachiStatus(port)
        check = _Guidedarm(
            "hardware-check", "path_following",
            "--set", f"station.hardware.arms.mz04d.port={port}",
            "--set", f"station.hardware.tof_tools.tof.device={device}",
        )  # fmt: skip
        after = _NachiStatus(port)
    finally:
        StopServer(emulator)
    assert check.returncode == 0, check.stdout + check.stderr
    assert before == after == "STATUS IDLE 0 0"
    assert "arm mz04d (nachi_tcp 127.0.0.1): STATUS IDLE 0 0" in check.stdout
    offsets = re.search(r"from the task's start pose \[([^\]]*)\] rad", check.stdout)[1]
    assert np.max(np.abs([float(x) for x in offsets.split(",")])) < 1e-4
    ranges = re.search(r"\n  (r1 .*)\n", check.stdout)[1]
    assert [field.split()[0] for field in ranges.split(", ")] == [f"r{i}" for i in range(1, 7)]
    assert re.search(r"tof tof \(serial /dev/pts/\d+\): \d+ lines/s", check.stdout)
    assert check.stdout.rstrip().endswith("hardware-check: every link answered")


def test_hardware_check_names_every_link_that_fails():
    result = _Guidedarm(
        "hardware-check", "path_following", "--set", "station.hardware.arms.mz04d.port=1",
        "--set", "station.hardware.tof_tools.tof.device=/dev/ttyUSB7",
    )  # fmt: skip
    assert result.returncode == 2, result.stdout + result.stderr
    assert "FAILED: mz04d: cannot reach 127.0.0.1:1: [Errno 111] Connection refused" in (
        result.stdout
    )
    assert "FAILED: tof: cannot open serial device '/dev/ttyUSB7'" in result.stdout
    assert (
        result.stderr.strip() == "guidedarm: error: hardware-check: mz04d, tof failed (see above)"
    )


def test_check_move_to_start_and_run_a_ur10e_from_power_on(tmp_path):
    """An emulated UR10e (lockstep) 0.1 rad from the tour's start: hardware-check reports the
    offset and
    starts no program; the run is refused naming every joint's offset; move-to-start brings
    the arm within the run's tolerance; the run then succeeds."""
    cell = UrCell(TOUR, "--lockstep", "--set", f"station.arms.ur10e.initial_position={AWAY}")
    host = f"station.hardware.arms.ur10e.host={cell.host}"
    # Lockstep: load-independent motion; a generous watchdog, as the link waits for each
    # sample and a host stall must not end a run that is not about wall-clock time.
    lockstep = (
        "--set",
        "station.hardware.arms.ur10e.lockstep=true",
        "--set",
        "station.hardware.arms.ur10e.watchdog=5",
    )
    try:
        check = _Guidedarm("hardware-check", TOUR, "--set", host)
        assert check.returncode == 0, check.stdout + check.stderr
        assert "runtime state 1" in check.stdout  # no program started
        assert "from the task's start pose [+0.1000, +0.0000, +0.0000" in check.stdout
        refused = _Guidedarm("run", TOUR, "--hardware", "--out", str(tmp_path / "a"), "--set", host)
        assert refused.returncode == 2
        assert "joint offsets [+0.1000, +0.0000, +0.0000, +0.0000, +0.0000, +0.0000] rad" in (
            refused.stderr
        )
        assert "guidedarm move-to-start SCENARIO --hardware" in refused.stderr
        move = _Guidedarm("move-to-start", TOUR, "--hardware", "--set", host, *lockstep)
        assert move.returncode == 0, move.stdout + move.stderr
        assert "ur10e moves 0.1000 rad (largest joint) in 1.10 s" in move.stdout
        assert f"at the start pose of '{TOUR}' (within 0.0001 rad)" in move.stdout
        out = str(tmp_path / "b")
        run = _Guidedarm("run", TOUR, "--hardware", "--out", out, "--set", host, *lockstep)
        assert run.returncode == 0, run.stdout + run.stderr
        assert "success: true" in run.stdout
    finally:
        output = cell.Close()
    assert "Traceback" not in output
