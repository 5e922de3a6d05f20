"""Faults injected through real processes during `guidedarm run path_following --hardware`
against `guidedarm emulate nachi` (a separate process): the controller killed (SIGKILL) or
frozen (SIGSTOP), a second client sending STOP as the pendant would, the ToF stream silenced
or garbled (a relay between the emulator's pseudo-terminal and the run's; silenced also
while following continuously), a command beyond the acceleration limits. Each run exits 1
within the watchdog + 1 s of the fault with summary.json naming the link, the fault and its
time, the emulated arm ends STOPPED when it is still reachable, and no output holds a
traceback.

Refusals before a run (a UR controller that cannot be reached, settings that cannot run on
hardware) are one line and exit 2.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import numpy as np
import pytest
from hardware_doubles import (
    FreezingNachiController,
    StartNachiEmulator,
    ToFRelay,
    WaitUntil,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.tasks.path_following import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.hardware.line_socket import LineSocket
from guidedarm.systems.hardware.nachi_link import NachiLink
from guidedarm.systems.hardware.tof_driver import ToFDriver
from guidedarm.systems.hardware.tof_protocol import FormatTofLine, ToFLineCollector
from guidedarm.systems.hardware.tof_transports import SerialTransport

WATCHDOG = 0.5  # s, arm and ToF tool: the emulator shares the 2 cores with the run
CLI = [sys.executable, "-m", "guidedarm.diagrams.cli.main"]
FAULT = r"hardware fault on {device} at t = \d+\.\d{{3}} s: "


def test_frozen_controller_is_sent_stop_within_watchdog_plus_a_period():
    # In process, to see when STOP reaches the controller: the link is dead (no replies), its
    # TCP connection open. A pending READ_JOINTS must not hold the STOP back.
    period, watchdog = 0.01, 0.1
    q0 = np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])
    controller = FreezingNachiController(q0)
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/mz04d/mz04d.urdf")
    plant.Finalize()
    limits = JointLimits.FromPlant(plant, instance, [10.0] * 6)
    link = NachiLink("mz04d", "127.0.0.1", controller.port, poll_period=period)
    builder = DiagramBuilder()
    driver = builder.AddSystem(ArmDriver(link, limits, period, watchdog, stale_after=0.05))
    source = builder.AddSystem(ConstantVectorSource(q0))
    builder.Connect(source.get_output_port(), driver.get_input_port())
    simulator = Simulator(builder.Build())
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(0.3)
    assert controller.logic.moves > 20  # streaming: about one target per period
    controller.frozen = True
    with pytest.raises(HardwareFaultError) as fault:
        simulator.AdvanceTo(5.0)
    controller.close()
    assert re.fullmatch(
        r"hardware fault on mz04d at t = 0\.\d{3} s: link quiet for 0\.1\d* s \(watchdog 0\.1 s\) "
        r"\(stopping it also failed: no reply to STOP within 0\.25 s\)",
        str(fault.value),
    )
    stops = [t for t, line in controller.received_frozen if line == "STOP"]
    assert len(stops) == 1
    delay = stops[0] - controller.last_measurement
    print(f"\nfrozen controller: last measurement to STOP received {delay:.3f} s")
    # Thread scheduling on the shared 2-core machine adds a few ms (up to tens under a load
    # average of 10) to the period.
    assert watchdog < delay < watchdog + period + 0.05
    # No target followed the STOP.
    after = [line for t, line in controller.received_frozen if t > stops[0]]
    assert not [line for line in after if line.startswith(("SET_TARGET", "MOVE"))]


class ScriptedNachiController:
    """A controller on 127.0.0.1 that answers RESET, SERVO and STOP with OK and READ_JOINTS
    with the arm at rest on the host clock, except that its `fault_at`-th reply to
    READ_JOINTS is sent twice (`duplicate`) or replaced by an OK (`swap`: the JOINTS
    reply lost, an OK in its place). It records the request lines."""

    def __init__(self, fault: str, fault_at: int = 5) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self.requests: list[str] = []
        self._fault, self._fault_at = fault, fault_at
        threading.Thread(target=self._Serve, daemon=True).start()

    def _Serve(self) -> None:
        connection, _ = self._server.accept()
        start, reads = time.monotonic(), 0
        lines = LineSocket(connection)
        with connection, contextlib.suppress(OSError):
            while True:
                line = lines.ReadLine()
                self.requests.append(line)
                if line != "READ_JOINTS":
                    lines.WriteLines("OK")
                    continue
                reads += 1
                joints = f"JOINTS {time.monotonic() - start:.4f} 0 90 0 0 -90 0"
                if reads != self._fault_at:
                    lines.WriteLines(joints)
                elif self._fault == "duplicate":
                    lines.WriteLines(joints, joints)
                else:
                    lines.WriteLines("OK")

    def close(self) -> None:
        self._server.close()


@pytest.mark.parametrize(
    "fault, message",
    [
        ("duplicate", r"a reply without a request: 'JOINTS \d+\.\d{4} 0 90 0 0 -90 0'"),
        ("swap", r"'OK' answered READ_JOINTS"),
    ],
)
def test_replies_out_of_step_fault_the_link_and_stop_is_unconfirmed(fault, message):
    """One reply too many or one of the wrong kind: every later reply could answer an
    earlier request (a stale JOINTS taken as new, an old OK as the STOP's), so the link
    faults at once; STOP is still sent, and reported unconfirmed."""
    controller = ScriptedNachiController(fault)
    link = NachiLink("mz04d", "127.0.0.1", controller.port, poll_period=0.005)
    try:

        def Faulted() -> bool:
            link.send_position(np.deg2rad([0, 90, 0, 0, -90, 0]), 0.005)
            return link.fault() is not None

        assert WaitUntil(Faulted)
        assert re.fullmatch("replies out of step with requests: " + message, link.fault() or "")
        with pytest.raises(ConnectionError, match="STOP sent, unconfirmed: replies out of step"):
            link.stop()
        assert WaitUntil(lambda: "STOP" in controller.requests)
    finally:
        link.close()
        controller.close()


@pytest.fixture(scope="module")
def q_start(tmp_path_factory) -> list[float]:
    """The task's start joints: the emulated arm starts there, as the real arm would be
    brought there before the run."""
    _, scenario, _ = LoadScenario("path_following", [])
    setup = MakeSetup(scenario, tmp_path_factory.mktemp("setup"))
    return [float(q) for q in setup.q_start]


class Cell:
    """The emulator process, its port and ToF device; its stderr goes to a file."""

    def __init__(self, q_start: list[float], tmp_path: Path) -> None:
        self.log = tmp_path / "emulator.log"
        with self.log.open("w") as log:
            self.process, self.port, self.tof_device = StartNachiEmulator(
                "--scenario",
                "path_following",
                "--set",
                f"station.arms.mz04d.initial_position={q_start}",
                "--servo-timeout",
                str(WATCHDOG),
                stderr=log,
            )

    def Request(self, line: str) -> str:
        """One request on a connection of its own (a second client, as a pendant)."""
        with socket.create_connection(("127.0.0.1", self.port), timeout=5.0) as connection:
            connection.sendall(f"{line}\n".encode())
            return connection.recv(256).decode().strip()

    def State(self) -> str:
        return self.Request("STATUS").split()[1]

    def Moves(self) -> int:
        return int(self.Request("STATUS").split()[2])

    def Close(self) -> str:
        """Ends the emulator; returns everything it printed."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGCONT)
            self.process.terminate()
        stdout, _ = self.process.communicate(timeout=10)
        return stdout + self.log.read_text()


@pytest.fixture
def cell(q_start, tmp_path):
    cell = Cell(q_start, tmp_path)
    yield cell
    output = cell.Close()
    assert "Traceback" not in output and "Failure at" not in output, output


class Run:
    """`guidedarm run path_following --hardware` against the cell, outputs to files."""

    def __init__(
        self,
        cell: Cell,
        out: Path,
        tof_device: str,
        *overrides: str,
        acceleration_limits: str = "[10, 10, 10, 10, 10, 10]",
    ) -> None:
        """overrides: `key=value` settings replacing the cell's defaults of the same key
        (`guidedarm run` refuses a key set twice)."""
        self.out = out
        out.mkdir()
        arm = (
            f"!NachiDriver {{port: {cell.port}, watchdog: {WATCHDOG}, "
            f"stale_after: 0.05, acceleration_limits: {acceleration_limits}}}"
        )
        settings = dict(
            s.split("=", 1)
            for s in [
                "station.arms.mz04d.control_period=0.01",
                "max_time=30",
                f"station.hardware.arms.mz04d={arm}",
                f"station.hardware.tof_tools.tof={{device: {tof_device}, watchdog: {WATCHDOG}}}",
                *overrides,
            ]
        )
        command = [*CLI, "run", "path_following", "--hardware", "--out", str(out / "run")]
        for key, value in settings.items():
            command += ["--set", f"{key}={value}"]
        self._stdout, self._stderr = (out / "stdout").open("w"), (out / "stderr").open("w")
        self.process = subprocess.Popen(command, stdout=self._stdout, stderr=self._stderr)

    def WaitUntilStreaming(self, cell: Cell, moves: int = 20) -> None:
        """Until the run has sent `moves` targets (it starts in a few seconds)."""
        deadline = time.monotonic() + 60.0
        while cell.Moves() < moves:
            assert self.process.poll() is None, self.Output()
            assert time.monotonic() < deadline, "the run did not start streaming"
            time.sleep(0.02)

    def Wait(self) -> float:
        """Waits for the exit; returns when it happened (time.monotonic())."""
        self.process.wait(timeout=60)
        return time.monotonic()

    def Output(self) -> str:
        self._stdout.flush()
        self._stderr.flush()
        return (self.out / "stdout").read_text() + (self.out / "stderr").read_text()

    def Summary(self) -> dict:
        return json.loads((self.out / "run" / "summary.json").read_text())

    def Failure(self) -> str:
        return self.Summary()["failure"]


def _CheckEnded(run: Run, fault: str, failure: str, fault_time: float) -> float:
    """The run exited 1 with `failure` (a regex) in summary.json, no traceback; returns
    the seconds from the fault to the run's line naming it (printed when the fault ends the
    simulation, before the summary, figures and replay of what was measured are written)."""
    deadline = time.monotonic() + 60.0
    while "writing the summary" not in (output := run.Output()):
        assert run.process.poll() is None, output
        assert time.monotonic() < deadline, output
        time.sleep(0.01)
    elapsed = time.monotonic() - fault_time
    run.Wait()
    output = run.Output()
    assert run.process.returncode == 1, output
    assert "Traceback" not in output and "Failure at" not in output, output
    assert re.fullmatch(failure, run.Failure()), run.Failure()
    assert f"guidedarm: run failed: {run.Failure()}" in output
    print(f"\n{fault}: fault to its line {elapsed:.3f} s; failure: {run.Failure()}")
    return elapsed


def _WaitForState(cell: Cell, state: str, timeout: float = 3.0) -> str:
    deadline = time.monotonic() + timeout
    while (current := cell.State()) != state and time.monotonic() < deadline:
        time.sleep(0.02)
    return current


ARM_FAULTS = {
    "kill": FAULT.format(device="mz04d")
    + r"connection lost: .* \(stopping it also failed: STOP not sent: the link is down\)",
    # The frozen process also emulates the ToF tool, whose watchdog may fire first (a line
    # the freeze cut short is rejected); the silence reported is the watchdog's or, on a
    # loaded machine, more.
    "freeze": "("
    + FAULT.format(device="mz04d")
    + r"link quiet for (0\.[5-9]|[1-9]\.)\d* s \(watchdog 0\.5 s\) "
    + r"\(stopping it also failed: no reply to STOP within 0\.25 s\)|"
    + FAULT.format(device="tof")
    + r"no valid line for (0\.[5-9]|[1-9]\.)\d* s \(watchdog 0\.5 s, [01] lines rejected\) "
    + r"\(stopping it also failed: mz04d: no reply to STOP within 0\.25 s\))",
    # On a loaded machine the driver may have skipped stale samples just before: the fault
    # then carries its hint on the streaming timeout.
    "pendant": FAULT.format(device="mz04d")
    + r"controller refused: 'NG E05 stopped; send RESET before SERVO'"
    + r"( \(no command sent for \d+ periods, .*\))?; arm stopped",
}


@pytest.mark.parametrize("fault", ARM_FAULTS)
def test_controller_fault_ends_the_run_with_a_summary(fault, cell, tmp_path):
    run = Run(cell, tmp_path / "out", cell.tof_device)
    run.WaitUntilStreaming(cell)
    fault_time = time.monotonic()
    if fault == "kill":
        cell.process.send_signal(signal.SIGKILL)
    elif fault == "freeze":
        cell.process.send_signal(signal.SIGSTOP)
    else:
        assert cell.Request("STOP") == "OK"
    elapsed = _CheckEnded(run, fault, ARM_FAULTS[fault], fault_time)
    assert elapsed < WATCHDOG + 1.0
    if fault == "freeze":
        # The STOP sent while the controller was frozen waits in its socket: it is executed
        # as soon as the controller runs again.
        cell.process.send_signal(signal.SIGCONT)
    if fault != "kill":
        assert _WaitForState(cell, "STOPPED") == "STOPPED"


TOF_FAULTS = {
    "silent": FAULT.format(device="tof")
    + r"no valid line for 0\.5\d* s \(watchdog 0\.5 s, 0 lines rejected\); arms stopped",
    "garbage": FAULT.format(device="tof")
    + r"no valid line for 0\.5\d* s \(watchdog 0\.5 s, [1-9]\d* lines rejected\); arms stopped",
}


@pytest.mark.parametrize("fault", TOF_FAULTS)
def test_tof_fault_stops_the_arm_and_ends_the_run(fault, cell, tmp_path):
    relay = ToFRelay(cell.tof_device)
    try:
        run = Run(cell, tmp_path / "out", relay.device)
        run.WaitUntilStreaming(cell)
        fault_time = time.monotonic()
        relay.mode = fault
        elapsed = _CheckEnded(run, f"tof {fault}", TOF_FAULTS[fault], fault_time)
    finally:
        relay.close()
    assert elapsed < WATCHDOG + 1.0
    assert cell.State() == "STOPPED"


# Continuous following streams a SERVO every 8 ms (tests/test_hardware_hil.py).
CONTINUOUS = (
    "motion=continuous",
    "estimator=ranging",
    "continuous.servo_period=0.008",
    "station.arms.mz04d.control_period=0.008",
)


def test_tof_silent_while_following_continuously_stops_the_arm(cell, tmp_path):
    """The tool moving at 30-50 mm/s when the ToF link goes quiet: the ToF watchdog stops
    the braking arm and ends the run as in stop-and-go."""
    relay = ToFRelay(cell.tof_device)
    try:
        run = Run(cell, tmp_path / "out", relay.device, *CONTINUOUS)
        run.WaitUntilStreaming(cell, moves=125)  # 1 s of targets: the tool is under way
        moving = cell.Request("READ_JOINTS"), time.sleep(0.05), cell.Request("READ_JOINTS")
        fault_time = time.monotonic()
        relay.mode = "silent"
        elapsed = _CheckEnded(run, "tof silent, continuous", TOF_FAULTS["silent"], fault_time)
    finally:
        relay.close()
    joints = [np.array(reply.split()[2:], float) for reply in moving[::2]]
    assert np.max(np.abs(joints[1] - joints[0])) > 0.01  # deg in 50 ms: it was moving
    # The summary keeps what the run measured before the fault: more than 1 s of following.
    summary = run.Summary()
    assert summary["sim_time_s"] > 1.0 and summary["average_speed_mm_s"] > 20.0, summary
    assert 0.0 < summary["coverage"] < 1.0 and summary["tracking_error_max_mm"] < 15.0, summary
    assert elapsed < WATCHDOG + 1.0
    assert cell.State() == "STOPPED"


def test_sigterm_while_streaming_stops_the_arm_before_the_report(cell, tmp_path):
    """SIGTERM while the arm follows continuously: STOP goes out at once, not after the
    seconds the interrupted run's figures and replay take (the emulator's streaming
    timeout, 0.5 s, would otherwise have latched TIMEOUT first); the summary says why."""
    run = Run(cell, tmp_path / "out", cell.tof_device, *CONTINUOUS)
    run.WaitUntilStreaming(cell, moves=60)
    signal_time = time.monotonic()
    run.process.send_signal(signal.SIGTERM)
    while (state := cell.State()) == "SERVO" and time.monotonic() - signal_time < 5.0:
        time.sleep(0.01)
    stopped_after = time.monotonic() - signal_time
    run.Wait()
    output = run.Output()
    print(f"\nSIGTERM while streaming: {state} after {stopped_after:.3f} s")
    assert state == "STOPPED" and stopped_after < WATCHDOG, (state, stopped_after)
    assert run.process.returncode == 1, output
    assert run.Failure() == "interrupted by SIGTERM"
    assert "Traceback" not in output


def test_refused_command_is_not_sent_and_ends_the_run(cell, tmp_path):
    # The follower accelerates its joints at up to 5 rad/s^2; the guard allows 0.05.
    limits = "[0.05, 0.05, 0.05, 0.05, 0.05, 0.05]"
    run = Run(cell, tmp_path / "out", cell.tof_device, acceleration_limits=limits)
    deadline = time.monotonic() + 60.0
    while cell.State() != "STOPPED":  # the refusal stops the arm: the fault's moment
        assert run.process.poll() is None, run.Output()
        assert time.monotonic() < deadline
        time.sleep(0.01)
    failure = FAULT.format(device="mz04d") + (
        r"command refused before sending: joint joint\d acceleration \S+ \|a\| > limit 0\.05; "
        "arm stopped"
    )
    elapsed = _CheckEnded(run, "refused command", failure, time.monotonic())
    assert elapsed < WATCHDOG + 1.0
    # Nothing beyond the limits reached the controller: every target it accepted is one
    # the guard passed, and none after the STOP.
    assert cell.Request("ERRORS") == "ERRORS 0"


def _RunRefused(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize(
    "args, message",
    [
        (
            [
                "run",
                "ur10e_joint_tour",
                "--hardware",
                "--set",
                "station.hardware.arms.ur10e=!UrRtdeDriver {host: 127.0.0.9, "
                "acceleration_limits: [5, 5, 5, 5, 5, 5]}",
            ],
            "ur10e: cannot connect to the UR controller at 127.0.0.9: RTDE 127.0.0.9:30004: "
            "[Errno 111] Connection refused",
        ),
        (["emulate", "nachi", "--port", "70000"], "--port: 70000 is not a TCP port (0..65535)"),
        (["emulate", "nachi", "--port", "-1"], "--port: -1 is not a TCP port (0..65535)"),
        (["emulate", "nachi", "--host", "no.such.host.invalid"], "--host 'no.such.host.invalid'"),
        (["emulate", "nachi", "--servo-timeout", "0"], "--servo-timeout 0.0: must be positive"),
        (
            ["emulate", "nachi", "--servo-acceleration", "nan"],
            "--servo-acceleration nan: must be positive and finite",
        ),
        (["emulate", "nachi", "--tof-latency", "-0.01"], "--tof-latency -0.01: must be >= 0"),
        (["emulate", "tof", "--tof-latency", "inf"], "--tof-latency inf: must be >= 0 and finite"),
        (["emulate", "tof", "--servo-timeout", "0.5"], "--servo-timeout applies to `emulate"),
        (
            ["emulate", "nachi", "--scenario", "ur10e_waypoints", "--arm", "ur10e"]
            + ["--tof-latency", "0.01", "--port", "0"],
            "--tof-latency: the station has no tof_tools",
        ),
        (
            ["run", "path_following", "--hardware", "--set"]
            + ["station.hardware.arms.mz04d=!NachiDriver {gain: 1000}"],
            "unknown key 'station.hardware.arms.mz04d.gain' (known keys: acceleration_limits, "
            "command_mode, host, lockstep, port, stale_after, watchdog)",
        ),
        (  # a DNS label longer than 63 characters: not a connection error of the socket
            ["run", "path_following", "--hardware", "--set"]
            + [f"station.hardware.arms.mz04d=!NachiDriver {{host: {'a' * 64}.cell}}"],
            f"'station.hardware.arms.mz04d.host': '{'a' * 64}.cell' is not a host name or "
            "address (encoding with 'idna' codec failed (UnicodeError: label empty or too long))",
        ),
    ],
)
def test_refusals_before_a_run_are_one_line(args, message, tmp_path):
    if args[0] == "run":
        args = [*args, "--out", str(tmp_path / "run")]
    result = _RunRefused(*args)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if not line.startswith("INFO:drake")]
    assert len(lines) == 1 and lines[0].startswith("guidedarm: error: "), result.stderr
    assert message in lines[0]
    assert "Traceback" not in result.stdout + result.stderr
    assert not (tmp_path / "run" / "summary.json").exists()


def test_an_arm_away_from_the_start_pose_is_refused_before_any_command(q_start, tmp_path):
    """The emulator solves its own start pose from a seed 0.3 rad (joint 1) away, which
    lands about 0.01 rad from the run's: the run refuses in one line naming the joint and
    the offset, exit 2, without a summary, and the arm never moved."""
    cell = Cell([q_start[0] + 0.3, *q_start[1:]], tmp_path)
    try:
        run = Run(cell, tmp_path / "out", cell.tof_device)
        run.Wait()
        output = run.Output()
        assert run.process.returncode == 2, output
        errors = [line for line in output.splitlines() if line.startswith("guidedarm: error")]
        assert len(errors) == 1, output
        assert re.fullmatch(
            r"guidedarm: error: mz04d is not at the task's start pose: joint offsets "
            r"\[([+-]\d\.\d{4}, ){5}[+-]\d\.\d{4}\] rad \(tolerance 0\.0001 rad\); bring it "
            r"there with `guidedarm move-to-start SCENARIO --hardware` and the run's --set "
            r"options \(an emulator: start it with --scenario and the run's --set options\)",
            errors[0],
        ), errors
        assert "Traceback" not in output and "Failure at" not in output
        assert not (tmp_path / "out" / "run" / "summary.json").exists()
        assert cell.Moves() == 0
    finally:
        cell.Close()


def test_a_link_to_a_host_name_idna_refuses_is_a_refusal():
    with pytest.raises(ConfigurationError, match=r"^mz04d: cannot reach a{64}\.cell:48000: "):
        NachiLink("mz04d", "a" * 64 + ".cell", 48000)


def test_a_tof_tool_resending_its_last_line_trips_the_watchdog():
    """The tool's firmware stuck resending one line over a real pty: the line is well
    formed, but its sequence number does not advance; the readings are stale, so the ToF
    watchdog stops the arms as for a silent tool, counting the resent lines."""
    master, slave = os.openpty()
    tty.setraw(slave)
    collector = ToFLineCollector()
    transport = SerialTransport(collector, os.ttyname(slave), 115200)
    driver = ToFDriver(collector, period=0.02, watchdog=0.2)
    simulator = Simulator(driver)
    simulator.set_target_realtime_rate(1.0)
    line = (FormatTofLine(7, np.full(6, 40), np.zeros(6, int)) + "\r\n").encode()
    stop = threading.Event()

    def resend() -> None:
        while not stop.wait(0.02):
            os.write(master, line)

    writer = threading.Thread(target=resend, daemon=True)
    writer.start()
    try:
        with pytest.raises(
            HardwareFaultError,
            match=r"on tof at t = 0\.\d+ s: no valid line for 0\.2\d* s \(watchdog 0\.2 s, "
            r"\d+ lines rejected\); arms stopped$",
        ):
            simulator.AdvanceTo(2.0)
        # well before the 2 s asked for (a bound for a loaded machine: 5 watchdogs)
        assert simulator.get_context().get_time() < 1.0
        assert collector.accepted == 1 and collector.rejected >= 1
    finally:
        stop.set()
        writer.join()
        transport.close()
        os.close(master)
        os.close(slave)


def test_a_joint_tour_arm_away_from_its_start_is_refused_before_any_command(tmp_path):
    """joint_tour streams its trajectory from the scenario's start: a UR10e (served by the
    Nachi emulator) 0.1 rad away on joint 1 is refused in one line, exit 2, no summary."""
    moved = "[-1.4708, -1.5708, -2.356194, -0.785398, 1.5708, 0.785398]"
    emulator = subprocess.Popen(
        [*CLI, "emulate", "nachi", "--port", "0", "--scenario", "ur10e_joint_tour"]
        + ["--arm", "ur10e", "--set", f"station.arms.ur10e.initial_position={moved}"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        port = int(emulator.stdout.readline().split(":")[-1])
        link = f"!NachiDriver {{port: {port}, acceleration_limits: [5, 5, 5, 5, 5, 5]}}"
        result = _RunRefused(
            "run", "ur10e_joint_tour", "--hardware", "--out", str(tmp_path / "run"),
            "--set", f"station.hardware.arms.ur10e={link}",
        )  # fmt: skip
        errors = [line for line in result.stderr.splitlines() if line.startswith("guidedarm:")]
        assert result.returncode == 2, result.stderr
        assert errors == [
            "guidedarm: error: ur10e is not at the task's start pose: joint offsets [+0.1000, "
            "+0.0000, +0.0000, +0.0000, +0.0000, +0.0000] rad (tolerance 0.0001 rad); bring it "
            "there with `guidedarm move-to-start SCENARIO --hardware` and the run's --set "
            "options (an emulator: start it with --scenario and the run's --set options)"
        ], result.stderr
        assert not (tmp_path / "run" / "summary.json").exists()
    finally:
        emulator.send_signal(signal.SIGINT)
        emulator.wait(timeout=30)
