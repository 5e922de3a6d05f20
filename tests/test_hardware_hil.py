"""Hardware in the loop: the path-following scenario run with `--hardware` against the Nachi
emulator (TCP) and the ToF emulator (pseudo-terminal) of `guidedarm emulate nachi`, both
separate processes, gives the same result as the simulated run."""

from __future__ import annotations

import json
import socket
import subprocess
import sys

import pytest
from hardware_doubles import StartNachiEmulator, StopServer

# The follower's moves are rest to rest with joint accelerations of at most 5 rad/s^2
# (joint_moves), so the acceleration guard runs at a plausible arm limit, 10 rad/s^2, the
# margin covering the driver's own timing (it streams at the follower's 10 ms period). The
# emulator shares the CPU with the client, so the watchdog is 0.5 s. The two runs cannot
# share a clock, so they sense at slightly different arm poses; the presence-only grid
# turns such differences into different steps now and then (7-8 steps apart in 1 of 4
# trials). The ranging estimator, continuous in the pose, keeps them within 2-4 of about 90
# steps in repeated trials, hence a tolerance of 5 % of the simulated steps.
COMMON = ["--set", "station.arms.mz04d.control_period=0.01", "--set", "estimator=ranging"]
ACCELERATION = "[10, 10, 10, 10, 10, 10]"


def _Run(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "run", "path_following", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def _Summary(out) -> dict:
    return json.loads((out / "summary.json").read_text())


def _Status(port: int) -> str:
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as connection:
        connection.sendall(b"STATUS\n")
        return connection.recv(256).decode().strip()


@pytest.mark.slow
def test_path_following_on_the_emulators_matches_simulation(tmp_path):
    sim_run = _Run("--out", str(tmp_path / "sim"), *COMMON)
    assert sim_run.returncode == 0, sim_run.stderr
    # The real arm would be brought to the start pose before the run: the emulator
    # simulates the station the task builds (task.Station), whose arm starts there.
    emulator, port, device = StartNachiEmulator(
        "--scenario", "path_following", "--servo-timeout", "0.5"
    )
    try:
        hardware_run = _Run(
            "--hardware",
            "--out",
            str(tmp_path / "hw"),
            *COMMON,
            "--set",
            "station.simulator_config.target_realtime_rate=1.0",
            "--set",
            f"station.hardware.arms.mz04d={{driver: nachi_tcp, port: {port}, "
            f"watchdog: 0.5, stale_after: 0.05, acceleration_limits: {ACCELERATION}}}",
            "--set",
            f"station.hardware.tof_tools.tof.device={device}",
        )
        status = _Status(port)
    finally:
        StopServer(emulator)
    assert hardware_run.returncode == 0, hardware_run.stderr
    for run in (sim_run, hardware_run):
        output = run.stdout + run.stderr
        assert "Traceback" not in output and "Failure at" not in output, output
    # The emulated arm was streamed (one SERVO per 10 ms) and stopped when the run ended.
    state, moves, errors = status.split()[1:]
    assert state == "STOPPED" and int(moves) > 1000 and errors == "0"
    sim, hw = _Summary(tmp_path / "sim"), _Summary(tmp_path / "hw")
    assert sim["success"] and hw["success"]
    assert hw["coverage"] == sim["coverage"]
    assert abs(hw["steps"] - sim["steps"]) <= 0.05 * sim["steps"]
    assert abs(hw["lost_steps"] - sim["lost_steps"]) <= 3
    assert hw["tracking_error_mean_mm"] == pytest.approx(sim["tracking_error_mean_mm"], abs=2.0)
    assert hw["collisions"] == sim["collisions"] == 0
