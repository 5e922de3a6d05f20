"""UR RTDE link: the vendor receive interface against the loopback RTDE double (a separate
process on 127.0.0.1:30004), the control side against a recording fake."""

from __future__ import annotations

import re
import socket
import subprocess
import threading
import time

import numpy as np
import pytest
from hardware_doubles import RecordingRtdeControl, StartServer, StopServer, WaitUntil
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.systems.errors import HardwareFaultError
from guidedarm.systems.hardware import rtde_protocol as rtde
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.arm_link import VendorThreadsAlive
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.hardware.ur_rtde_link import RTDE_FREQUENCY, UrRtdeLink

rtde_receive = pytest.importorskip("rtde_receive")

# The watchdog's fault, with the quiet time it judged (s).
QUIET = r"ur10e at .*: link quiet for ([0-9.]+) s \(watchdog 0.1 s\)"

Q_DOUBLE = [-1.5708, -1.5708, -2.3562, -0.7854, 1.5708, 0.7854]


def _Limits() -> JointLimits:
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/ur10e/ur10e.urdf")
    plant.Finalize()
    return JointLimits.FromPlant(plant, instance, [10.0] * 6)


def _Connect(*double_args: str):
    process, _ = StartServer(
        "guidedarm.systems.hardware.rtde_double", "--q", *map(str, Q_DOUBLE), *double_args
    )
    receive = rtde_receive.RTDEReceiveInterface(
        "127.0.0.1", RTDE_FREQUENCY, ["timestamp", "actual_q", "actual_qd"]
    )
    control = RecordingRtdeControl()
    return process, receive, control, UrRtdeLink("ur10e", receive, control)


def _RunDriver(link, t_final: float, watchdog: float = 0.1) -> tuple[ArmDriver, Simulator]:
    driver = ArmDriver(link, _Limits(), period=0.002, watchdog=watchdog, stale_after=0.02)
    simulator = Simulator(driver)
    driver.get_input_port().FixValue(simulator.get_mutable_context(), Q_DOUBLE)
    simulator.set_target_realtime_rate(1.0)
    simulator.Initialize()
    simulator.AdvanceTo(t_final)
    return driver, simulator


def test_receive_side_reads_the_double_at_500_hz_and_streams_servoj():
    connected = time.monotonic()
    process, receive, control, link = _Connect()
    try:
        deadline = time.monotonic() + 5.0
        while link.latest() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        np.testing.assert_allclose(link.latest().q, Q_DOUBLE, atol=1e-12)
        # The controller clock counts seconds since the stream started: it reaches 0.5 s
        # (5 s is a bound for a loaded machine), and never runs ahead of the host's.
        while receive.getTimestamp() < 0.5 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert 0.5 <= receive.getTimestamp() <= time.monotonic() - connected
        driver, simulator = _RunDriver(link, 0.3)
        measured = driver.GetOutputPort("state_estimated").Eval(simulator.get_context())
        np.testing.assert_allclose(measured, Q_DOUBLE + [0.0] * 6, atol=1e-12)
        servo = [c for c in control.calls if c[0] == "servoJ"]
        # 0.3 s at 500 Hz: each of the 150 periods in [0, 0.3) sends a servoJ or skips a
        # stale sample (a busy CPU delays the double's samples), and each servoJ's time is
        # the interval since the previous one, whole periods.
        assert len(servo) >= 1 and len(servo) + driver.stale_skips == 150
        assert servo[-1][1][0] == pytest.approx(Q_DOUBLE)
        periods = np.array([c[1][1] for c in servo]) / 0.002
        np.testing.assert_allclose(periods, np.maximum(1, np.round(periods)), atol=1e-6)
        # The controller's streaming timeout: 0.1 s, fed by every servoJ itself (a kick
        # right after it could overwrite the servoJ command before the script reads it),
        # by kicks before the first one only.
        assert control.calls[0] == ("setWatchdog", (10.0,), control.calls[0][2])
        first = next(i for i, call in enumerate(control.calls) if call[0] == "servoJ")
        assert all(call[0] != "kickWatchdog" for call in control.calls[first:])
    finally:
        link.close()
        StopServer(process)
    assert control.Count("stopScript") == 1


def test_quiet_link_stops_the_robot_and_fails_the_run():
    process, _, control, link = _Connect("--quiet-after", "0.3")
    try:
        with pytest.raises(HardwareFaultError, match=QUIET) as fault:
            _RunDriver(link, 5.0)
        assert control.Count("servoStop") == 1
        assert control.calls[-1][0] == "servoStop"
        # Stopped after the watchdog on the samples the driver had (a sample the starved
        # poll thread reads after the verdict may be newer), within a bound for a loaded
        # machine (10 watchdogs) of the last one, and no command followed the last fresh
        # sample by more than the staleness bound.
        assert float(re.search(QUIET, str(fault.value))[1]) >= 0.1
        last_sample = link.latest().host_time
        assert control.calls[-1][2] - last_sample < 1.0
        late = [c for c in control.calls if c[0] == "servoJ" and c[2] > last_sample + 0.025]
        assert late == []
    finally:
        link.close()
        StopServer(process)


def test_timestamps_running_backwards_are_stale_and_trip_the_watchdog():
    """The controller keeps streaming, its `timestamp` running backwards after 0.3 s: its
    samples are not new (they were taken as new while they differed from the last one), so
    no command follows them and the watchdog stops the robot."""
    process, _, control, link = _Connect("--backwards-after", "0.3")
    try:
        with pytest.raises(HardwareFaultError, match=QUIET) as fault:
            _RunDriver(link, 5.0)
        assert control.Count("servoStop") == 1
        assert float(re.search(QUIET, str(fault.value))[1]) >= 0.1
        assert control.calls[-1][2] - link.latest().host_time < 1.0
    finally:
        link.close()
        StopServer(process)


def test_double_rejects_malformed_packets_and_keeps_serving():
    process, port = StartServer(
        "guidedarm.systems.hardware.rtde_double", "--port", "0", stderr=subprocess.PIPE
    )
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2.0) as connection:
            buffer = bytearray()

            def reply() -> rtde.Packet:
                while not (packets := rtde.SplitPackets(buffer)):
                    buffer.extend(connection.recv(4096))
                return packets[0]

            connection.sendall(rtde.EncodePacket(ord("X"), b"junk"))
            assert reply().type == rtde.TEXT_MESSAGE
            connection.sendall(rtde.EncodePacket(rtde.REQUEST_PROTOCOL_VERSION, b"\x00\x02"))
            assert reply() == rtde.Packet(rtde.REQUEST_PROTOCOL_VERSION, b"\x01")
    finally:
        process.terminate()
        _, stderr = process.communicate(timeout=5)
    assert "rejected packet #1: unexpected RTDE packet type 88 (4 B)" in stderr


def test_split_packets_keeps_a_truncated_tail_and_rejects_a_bad_size():
    whole = rtde.EncodePacket(rtde.CONTROL_PACKAGE_START)
    buffer = bytearray(whole + whole[:2])
    assert rtde.SplitPackets(buffer) == [rtde.Packet(rtde.CONTROL_PACKAGE_START, b"")]
    assert buffer == whole[:2]
    with pytest.raises(rtde.RtdeProtocolError, match="size 1 is smaller than its header"):
        rtde.SplitPackets(bytearray(b"\x00\x01U"))


class _ReceiveThatHangsOnDisconnect:
    """The receive side of a controller that answers reads but whose disconnect waits until
    `answer` is set (a controller that stopped answering its shutdown)."""

    def __init__(self, answer: threading.Event) -> None:
        self._answer = answer

    def isConnected(self) -> bool:
        return True

    def getTimestamp(self) -> float:
        return 0.0

    def getActualQ(self) -> list[float]:
        return Q_DOUBLE

    def getActualQd(self) -> list[float]:
        return [0.0] * 6

    def getRuntimeState(self) -> int:
        return 1

    def disconnect(self) -> None:
        self._answer.wait()


def test_a_disconnect_left_behind_is_reported_so_the_process_ends_without_teardown():
    """close() returns after CLOSE_TIMEOUT although the disconnect hangs; the call left
    behind is a vendor thread still alive (the CLI then ends with os._exit), until it
    returns; the control script is stopped after the receive side is released."""
    answer = threading.Event()
    control = RecordingRtdeControl()
    link = UrRtdeLink("ur10e", _ReceiveThatHangsOnDisconnect(answer), control)
    link.close()
    assert VendorThreadsAlive()
    assert control.Count("stopScript") == 0
    answer.set()
    assert WaitUntil(lambda: not VendorThreadsAlive())
    assert control.Count("stopScript") == 1
