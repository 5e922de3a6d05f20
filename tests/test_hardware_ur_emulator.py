"""`guidedarm emulate ur`: the UR controller emulator's register protocol (without a
simulation), and the real ur_rtde client driving the UR10e tasks through it: success,
tracking, and a killed, frozen or dashboard-stopped controller ending the run with a
summary naming the arm."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_hardware_link_checks import FreeLoopbackHost

from guidedarm.systems.hardware.ur_controller_logic import (
    DONE,
    PLAYING,
    READY,
    SERVOJ,
    SET_WATCHDOG,
    STOPPED,
    UrControllerLogic,
)

CLI = [sys.executable, "-m", "guidedarm.diagrams.cli.main"]
WATCHDOG = 0.5  # s, the arm driver's default
DT = 0.002  # s, the controller's step


def _Logic() -> UrControllerLogic:
    n = 6
    return UrControllerLogic(
        np.full(n, -6.0), np.full(n, 6.0), np.zeros(n), np.full(n, 2.0), np.full(n, 10.0)
    )


def _Run(logic: UrControllerLogic, t0: float, seconds: float) -> float:
    """Steps the logic with the arm exactly where it is commanded; returns the end time."""
    t = t0
    for _ in range(round(seconds / DT)):
        t += DT
        logic.Step(t, logic.commanded, np.zeros(6))
    return t


def _ServoJ(q, interval: float) -> dict:
    registers = {f"input_double_register_{i}": value for i, value in enumerate(q)}
    return {"input_int_register_0": SERVOJ, **registers, "input_double_register_8": interval}


def test_the_control_script_protocol_tracks_servoj_and_its_watchdog_stops_the_program():
    logic = _Logic()
    assert logic.StartProgram("def other():\n  movej([0,0,0,0,0,0])\n").startswith(
        "program refused"
    )
    assert logic.Output("runtime_state") == STOPPED
    logic.StartProgram("def rtde_control():\n  # the control script\n")
    assert logic.Output("runtime_state") == PLAYING
    assert logic.Output("output_int_register_0") == READY
    # setWatchdog(10 Hz): a command the client waits for (done), then NO_CMD (ready).
    logic.WriteInputs({"input_int_register_0": SET_WATCHDOG, "input_double_register_0": 10.0})
    t = _Run(logic, 0.0, DT)
    assert logic.Output("output_int_register_0") == DONE
    logic.WriteInputs({"input_int_register_0": 0})
    t = _Run(logic, t, DT)
    assert logic.Output("output_int_register_0") == READY
    # A stream of 50 targets 0.5 mrad apart on joint 1 (0.25 rad/s), one per step: tracked.
    for k in range(1, 51):
        logic.WriteInputs(_ServoJ([0.0005 * k, 0, 0, 0, 0, 0], DT))
        t = _Run(logic, t, DT)
    t = _Run(logic, t, 0.05)  # the stream stops; the watchdog (0.1 s) has not yet expired
    assert logic.Output("runtime_state") == PLAYING
    assert logic.commanded[0] == pytest.approx(0.025, abs=2e-3)  # the servo loop settles
    assert logic.servo_targets == 50
    t = _Run(logic, t, 0.06)  # 0.11 s since the last write
    assert logic.Output("runtime_state") == STOPPED
    assert "RTDE watchdog: input_int_register_0 not written for 0.1" in logic.stop_reason


def test_the_dashboard_answers_ur_rtde_and_stop_ends_the_program():
    logic = _Logic()
    logic.StartProgram("def rtde_control():\n")
    assert logic.Dashboard("PolyscopeVersion\n").startswith("URSoftware 5.15.0.0")
    assert logic.Dashboard("is in remote control") == "true"
    assert logic.Dashboard("running") == "Program running: true"
    assert logic.Dashboard("stop") == "Stopped"
    assert logic.Output("runtime_state") == STOPPED
    assert logic.Dashboard("no such request") == "could not understand: 'no such request'"


@pytest.mark.parametrize(
    "option, message",
    [
        (["--port", "30004"], "--port: not for `emulate ur`: ur_rtde connects to the fixed"),
        (["--servo-timeout", "0.1"], "--servo-timeout: not for `emulate ur`: the UR's"),
        (["--host", "192.0.2.1"], "--host '192.0.2.1': cannot listen there"),
    ],
)
def test_emulate_ur_refuses_what_it_does_not_read(option, message):
    result = subprocess.run(
        [*CLI, "emulate", "ur", *option], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    assert result.stderr.startswith(f"guidedarm: error: {message}"), result.stderr


class UrCell:
    """`guidedarm emulate ur --scenario SCENARIO` on a loopback address of its own."""

    def __init__(self, scenario: str, *options: str) -> None:
        self.host = FreeLoopbackHost()
        self.process = subprocess.Popen(
            [*CLI, "emulate", "ur", "--scenario", scenario, "--host", self.host, *options],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        line = self.process.stdout.readline()
        assert line.startswith(f"ur: ur10e listening on {self.host}"), line

    def Dashboard(self, request: str) -> str:
        with socket.create_connection((self.host, 29999), timeout=5) as connection:
            reader = connection.makefile("r")
            reader.readline()
            connection.sendall(f"{request}\n".encode())
            return reader.readline().strip()

    def Close(self) -> str:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGCONT)
            self.process.send_signal(signal.SIGINT)
        output, _ = self.process.communicate(timeout=30)
        return output


def _StartRun(cell: UrCell, scenario: str, out: Path, *overrides: str) -> subprocess.Popen:
    """The scenario's own driver settings (their defaults: watchdog 0.5 s), the host set."""
    command = [*CLI, "run", scenario, "--hardware", "--out", str(out)]
    for override in (f"station.hardware.arms.ur10e.host={cell.host}", *overrides):
        command += ["--set", override]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["ur10e_joint_tour", "ur10e_waypoints"])
def test_ur10e_tasks_through_the_real_ur_rtde_client(scenario, tmp_path):
    """In lockstep (the emulator's clock is the servoJ stream's, the link waits for the
    joints after each target), so that the figures do not depend on the host's load: the
    run succeeds by the task's own verdict, the measured arm follows the stream one control
    period behind (2 ms) within a few mrad, the planner's run ends as simulated (T = 4.52 s,
    its joint accelerations within 80 deg/s^2) with the TCP within 5 mm of its stream."""
    cell = UrCell(scenario, "--lockstep")
    try:
        # In lockstep the link waits for each sample; a generous watchdog keeps a host
        # stall from ending a run that judges tracking, not wall-clock behaviour.
        lockstep = (
            "station.hardware.arms.ur10e.lockstep=true",
            "station.hardware.arms.ur10e.watchdog=5",
        )
        run = _StartRun(cell, scenario, tmp_path / "run", *lockstep)
        output, _ = run.communicate(timeout=300)
    finally:
        emulator = cell.Close()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    print(f"\n{scenario}: {json.dumps({k: v for k, v in summary.items() if k != 'command'})}")
    print(emulator.splitlines()[-2])
    assert run.returncode == 0 and summary["success"] is True, (output, summary)
    assert "rtde_control started" in emulator and "0 unsupported commands" in emulator
    assert summary["tracking_delay_s"] == pytest.approx(0.002)
    assert summary["tracking_error_max_rad"] < 0.005
    if scenario == "ur10e_waypoints":
        assert summary["T_s"] == pytest.approx(4.52, abs=0.01)
        assert max(summary["qdd_max"], -summary["qdd_min"]) <= np.radians(80) + 1e-9
        assert summary["tcp_tracking_error_max_m"] < 0.005
    else:
        assert summary["final_error_rad"] < 1e-6
    assert "Traceback" not in output + emulator


FAULTS = {
    "killed": (
        lambda cell: cell.process.send_signal(signal.SIGKILL),
        # Which of the link's reads or writes meets the dead socket first depends on where
        # in its period the kill lands; each names the lost link.
        r"hardware fault on ur10e at t = .* s: (RTDE connection lost|RTDE receive failed|"
        r"command not sent)\b.*",
    ),
    "frozen": (
        lambda cell: cell.process.send_signal(signal.SIGSTOP),
        rf"hardware fault on ur10e at t = .* s: link quiet for .* s \(watchdog {WATCHDOG} s\) "
        r"\(stopping it also failed: servoStop unconfirmed within 0.25 s\)",
    ),
    "stopped from the dashboard": (
        lambda cell: cell.Dashboard("stop"),
        r"hardware fault on ur10e at t = .* s: command not sent: servoJ not accepted: the "
        r"control program has stopped .*; arm stopped",
    ),
}


@pytest.mark.parametrize("fault", FAULTS)
def test_a_controller_fault_stops_the_run_within_the_watchdog_and_a_second(fault, tmp_path):
    inject, failure = FAULTS[fault]
    cell = UrCell("ur10e_joint_tour")
    try:
        # At a tenth of the tour's speed it lasts about 30 s: the fault lands mid-run
        # however late this process reads the run's first progress line.
        run = _StartRun(cell, "ur10e_joint_tour", tmp_path / "run", "max_speed=0.08")
        lines, elapsed = [], None
        for line in run.stdout:  # the tour is under way at 0.25 s of its 4.2 s
            lines.append(line)
            if "simulated" in line:
                break
        inject(cell)
        fault_time = time.monotonic()
        for line in run.stdout:
            lines.append(line)
            if line.startswith("  failure:"):  # printed once summary.json is written
                elapsed = time.monotonic() - fault_time
                break
        lines.append(run.communicate(timeout=60)[0])
    finally:
        cell.Close()
    output = "".join(lines)
    assert run.returncode == 1 and elapsed is not None, (run.returncode, output)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    print(f"\n{fault}: fault to its line {elapsed:.3f} s; failure: {summary['failure']}")
    assert re.fullmatch(failure, summary["failure"]), summary["failure"]
    # A generous bound (the figure itself, 0.04-0.8 s on an idle host, is printed above):
    # the run must stop long before the tour's 30 s, whatever else the host is doing.
    assert elapsed < 20 * WATCHDOG
    assert "Traceback" not in output
