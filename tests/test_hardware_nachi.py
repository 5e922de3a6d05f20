"""Nachi MZ04D: the User Task protocol, the emulator (Drake simulation of the cell) and the
client link through a real TCP socket on 127.0.0.1."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hardware_doubles import LOADED_MACHINE_BOUND, RELAXED_SERVO_TIMEOUT, Mz04dScenario, WaitUntil
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.station.hardware_config import HardwareConfig, NachiDriver
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.nachi_emulator import NachiControllerLogic, NachiEmulator
from guidedarm.systems.hardware.nachi_link import NachiLink

HOME = np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])
ACCELERATION = [20.0] * 6


def _Logic() -> NachiControllerLogic:
    return NachiControllerLogic(np.full(6, -1.0), np.full(6, 1.0), np.zeros(6))


@pytest.mark.parametrize(
    "requests, last_reply",
    [
        (["READ_JOINTS"], "JOINTS 0.0000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000"),
        (["MOVE"], "NG E04 MOVE without SET_TARGET"),
        (["SET_TARGET 0 0 0 0 0 60"], "NG E03 joint6 target beyond its limits"),
        (["SET_TARGET 1 2"], "NG E02 expected 6 numbers, got 2: 'SET_TARGET 1 2'"),
        (["SET_TARGET 1 2 3 4 5 x"], "NG E02 not a number in 'SET_TARGET 1 2 3 4 5 x'"),
        (["SET_TARGET 1 2 3 4 5 nan"], "NG E02 non-finite number in 'SET_TARGET 1 2 3 4 5 nan'"),
        (["JUMP"], "NG E01 unknown request 'JUMP'"),
        (["x" * 300], "NG E02 line longer than 256 bytes"),
        (["SET_TARGET 10 0 0 0 0 0", "MOVE", "STATUS"], "STATUS MOVING 1 0"),
        (["SET_TARGET 10 0 0 0 0 0", "STOP", "MOVE"], "NG E05 stopped; send RESET before MOVE"),
        (["STOP", "RESET", "STATUS"], "STATUS IDLE 0 0"),
        (["JUMP", "MOVE", "ERRORS"], "ERRORS 2 E04 MOVE without SET_TARGET"),
        # Streaming (joint limits here: 1 rad, pi rad/s): the interval, range and implied
        # velocity are checked before a target is tracked.
        (["SERVO 0.01 1 0 0 0 0 0", "STATUS"], "STATUS SERVO 1 0"),
        (["SERVO 0.01 1 0 0 0"], "NG E02 expected 7 numbers, got 5: 'SERVO 0.01 1 0 0 0'"),
        (["SERVO 0 1 0 0 0 0 0"], "NG E06 SERVO interval 0 s outside (0, 1] s"),
        (["SERVO 1.5 1 0 0 0 0 0"], "NG E06 SERVO interval 1.5 s outside (0, 1] s"),
        (["SERVO 0.01 0 0 60 0 0 0"], "NG E03 joint3 target beyond its limits"),
        (
            ["SERVO 0.01 1 0 0 0 0 0", "SERVO 0.01 3 0 0 0 0 0"],
            "NG E06 joint1 SERVO step implies 3.491 rad/s, beyond its limit 3.142",
        ),
        (
            ["SERVO 0.01 1 0 0 0 0 0", "STOP", "SERVO 0.01 1 0 0 0 0 0"],
            "NG E05 stopped; send RESET before SERVO",
        ),
        (
            ["SERVO 0.01 1 0 0 0 0 0", "SET_TARGET 1 0 0 0 0 0", "MOVE"],
            "NG E08 MOVE while streaming; send STOP first",
        ),
        (
            ["SERVO 0.01 1 0 0 0 0 0", "STOP", "RESET", "SERVO 0.01 1 0 0 0 0 0"],
            "NG E08 SERVO while the arm still brakes",
        ),
    ],
)
def test_controller_logic_replies(requests, last_reply):
    logic = _Logic()
    replies = [logic.Handle(r) for r in requests]
    assert replies[-1] == last_reply


def test_set_target_moves_the_command_in_radians():
    logic = _Logic()
    logic.Handle("SET_TARGET 10 0 0 0 0 -20")
    logic.Handle("MOVE")
    np.testing.assert_allclose(logic.commanded, np.deg2rad([10, 0, 0, 0, 0, -20]))


@pytest.fixture
def emulator():
    station = MakeStation(Mz04dScenario())
    emulator = NachiEmulator(station, "mz04d", port=0, servo_timeout=RELAXED_SERVO_TIMEOUT)
    thread = threading.Thread(target=emulator.Run, kwargs={"duration": 30.0}, daemon=True)
    thread.start()
    yield emulator
    emulator.Close()
    thread.join(timeout=2.0)


def _Hardware(port: int, watchdog: float = 0.5, command_mode: str = "stream"):
    """Hardware section for the emulator; the watchdog is generous because the emulator
    shares the CPU (and the GIL) with the driver under test."""
    arm = NachiDriver(
        port=port,
        watchdog=watchdog,
        acceleration_limits=ACCELERATION,
        command_mode=command_mode,
    )
    return Mz04dScenario(hardware=HardwareConfig(arms={"mz04d": arm}))


def _Diagram(scenario, source):
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(scenario, kind="hardware"))
    builder.AddSystem(source)
    builder.Connect(source.get_output_port(), station.GetInputPort("mz04d.position_commanded"))
    simulator = Simulator(builder.Build())
    simulator.set_target_realtime_rate(1.0)
    return station, simulator


def test_pose_reply_matches_forward_kinematics(emulator):
    link = NachiLink("mz04d", "127.0.0.1", emulator.port)
    time.sleep(0.05)
    (reply,) = link.Request(nachi.READ_POSE)
    xyz, rpy = nachi.ParsePose(reply)
    # Home pose of models/mz04d/home.yaml: flange straight down at (0.280, 0, 0.553) m.
    np.testing.assert_allclose(xyz, [0.280, 0.0, 0.553], atol=2e-3)
    np.testing.assert_allclose(np.abs(rpy[0]), np.pi, atol=2e-3)
    link.close()


@pytest.mark.parametrize("command_mode", ["stream", "move"])
def test_hardware_station_moves_the_emulated_arm(emulator, command_mode):
    # joint1 by 0.1 rad in 0.4 s (cubic): at most 0.375 rad/s and 3.75 rad/s^2.
    goal = HOME + np.array([0.1, 0, 0, 0, 0, 0])
    motion = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, 0.4], np.column_stack([HOME, goal]), np.zeros(6), np.zeros(6)
    )
    scenario = _Hardware(emulator.port, command_mode=command_mode)
    station, simulator = _Diagram(scenario, TrajectorySource(motion))
    simulator.AdvanceTo(1.2)
    context = station.GetMyContextFromRoot(simulator.get_context())
    # Streamed, the controller's servo loop has settled onto the last target by now.
    np.testing.assert_allclose(emulator.logic.commanded, goal, atol=1e-9)
    np.testing.assert_allclose(emulator.logic.measured, goal, atol=1e-3)
    measured = station.GetOutputPort("mz04d.position_measured").Eval(context)
    np.testing.assert_allclose(measured, goal, atol=1e-3)
    assert emulator.logic.moves > 100  # 400 periods; a target per period unless stale
    assert emulator.logic.State() == ("SERVO" if command_mode == "stream" else "IDLE")


def test_frozen_controller_trips_the_watchdog_and_is_stopped(emulator):
    _, simulator = _Diagram(_Hardware(emulator.port, watchdog=0.5), ConstantVectorSource(HOME))
    simulator.AdvanceTo(0.2)
    emulator.Close()  # the simulation stops; the open connection answers with frozen joints
    with pytest.raises(
        HardwareFaultError, match=r"mz04d at t = \S+ s: link quiet for \S+ s .*; arm stopped$"
    ) as fault:
        simulator.AdvanceTo(5.0)
    # after the freeze and the watchdog (0.5 s: a 0.1 s one tripped before the freeze when
    # the shared CPU stalled the in-process emulator), before the 5 s asked for
    quiet = float(re.search(r"link quiet for (\S+) s", str(fault.value))[1])
    assert quiet >= 0.5 and fault.value.t > 0.2
    assert emulator.logic.stops == 1 and emulator.logic.State() == "STOPPED"


@pytest.mark.parametrize(
    "command_mode, word, state", [("stream", "SERVO", "SERVO"), ("move", "MOVE", "IDLE")]
)
def test_stop_from_the_pendant_fails_the_run_and_a_new_run_resets_it(
    emulator, command_mode, word, state
):
    scenario = _Hardware(emulator.port, command_mode=command_mode)
    _, simulator = _Diagram(scenario, ConstantVectorSource(HOME))
    simulator.AdvanceTo(0.1)
    with socket.create_connection(("127.0.0.1", emulator.port)) as pendant:
        pendant.sendall(b"STOP\n")
        assert pendant.recv(16) == b"OK\n"
    with pytest.raises(
        HardwareFaultError,
        # A host too busy to keep the samples fresh adds why no command went out since.
        match=f"mz04d at t = .*: controller refused: 'NG E05 stopped; send RESET before "
        f"{word}'( \\(no command sent for .*\\))?; arm stopped$",
    ):
        simulator.AdvanceTo(1.0)
    assert emulator.logic.State() == "STOPPED"
    moves = emulator.logic.moves
    _, simulator = _Diagram(scenario, ConstantVectorSource(HOME))
    simulator.AdvanceTo(0.1)
    assert emulator.logic.State() == state and emulator.logic.moves > moves


def test_malformed_replies_are_counted_and_the_link_keeps_reading(capsys):
    server = socket.create_server(("127.0.0.1", 0))
    replies = [  # OK: to RESET; then malformed, binary and non-ASCII replies to READ_JOINTS
        "OK",
        "JOINTS 1.0 a b c d e f",
        "JOINTS 2.0 1 2 3",
        "BANANA",
        "JOINTS 3.0 1 2 3 4 5 \x00",
        "JOINTS 4.0 1 2 3 4 5 6\u00e9",
    ]

    def controller():
        connection, _ = server.accept()
        with connection, connection.makefile("rw", newline="\n") as stream:
            for k, _ in enumerate(stream):
                good = f"JOINTS {k * 0.002:.4f} 1 2 3 4 5 6"
                stream.write((replies[k] if k < len(replies) else good) + "\n")
                stream.flush()

    threading.Thread(target=controller, daemon=True).start()
    link = NachiLink("mz04d", "127.0.0.1", server.getsockname()[1])
    assert WaitUntil(lambda: link.rejected_lines >= 5 and link.latest() is not None)
    assert link.rejected_lines == 5 and link.fault() is None
    np.testing.assert_allclose(link.latest().q, np.deg2rad([1, 2, 3, 4, 5, 6]))
    now = time.monotonic()  # the link keeps reading the good replies after the bad ones
    assert WaitUntil(lambda: link.latest().host_time > now)
    link.close()
    # Only the 1st, 10th, 100th, ... rejection is printed.
    printed = [line for line in capsys.readouterr().out.splitlines() if "rejected reply" in line]
    assert len(printed) == 1 and printed[0].startswith("mz04d: rejected reply #1: ")
    server.close()


@pytest.mark.parametrize("reply", ["NG E05 stopped", None])
def test_controller_refusing_reset_is_a_one_line_refusal(reply):
    """A controller that answers RESET with NG, or not at all, is refused before any run."""
    server = socket.create_server(("127.0.0.1", 0))

    def controller():
        connection, _ = server.accept()
        with connection, connection.makefile("rw", newline="\n") as stream:
            for _ in stream:
                if reply is not None:
                    stream.write(reply + "\n")
                    stream.flush()

    threading.Thread(target=controller, daemon=True).start()
    port = server.getsockname()[1]
    with pytest.raises(ConfigurationError, match=rf"mz04d: 127.0.0.1:{port} did not accept RESET"):
        NachiLink("mz04d", "127.0.0.1", port, connect_timeout=0.3)
    server.close()


# A script run from a terminal, where Ctrl-C raises KeyboardInterrupt. Set explicitly: a
# process inherits an ignored SIGINT (a suite started as a background job of a shell), and
# Python then leaves it ignored.
HOLD_SCRIPT = """
import signal
import sys
signal.signal(signal.SIGINT, signal.default_int_handler)
sys.path.insert(0, {tests!r})
from pydrake.systems.primitives import ConstantVectorSource
from test_hardware_nachi import HOME, _Diagram, _Hardware
station, simulator = _Diagram(_Hardware({port}), ConstantVectorSource(HOME))
simulator.AdvanceTo(0.1)
print("running", flush=True)
simulator.AdvanceTo(60.0)
"""


def test_ctrl_c_stops_the_robot(emulator, tmp_path):
    script = tmp_path / "hold.py"
    script.write_text(HOLD_SCRIPT.format(tests=str(Path(__file__).parent), port=emulator.port))
    process = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert process.stdout.readline().strip() == "running"
    moves_before = emulator.logic.moves
    assert WaitUntil(lambda: emulator.logic.moves > moves_before)  # it is streaming
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=12 * LOADED_MACHINE_BOUND)
    assert "KeyboardInterrupt" in stderr
    assert emulator.logic.stops == 1 and emulator.logic.State() == "STOPPED"
