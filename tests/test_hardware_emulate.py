"""`guidedarm emulate nachi`: a separate process serving the MZ04D over TCP and the ToF tool
over a pseudo-terminal, read back with the project's own drivers."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest
from hardware_doubles import StartNachiEmulator, StopServer
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.emulation import DEFAULT_TOF_LATENCY, DefaultCell
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.nachi_link import NachiLink
from guidedarm.systems.hardware.tof_driver import ToFDriver
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector
from guidedarm.systems.hardware.tof_transports import SerialTransport
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig

HOME = np.array([0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])


def test_emulate_nachi_serves_the_arm_and_the_tof_tool():
    process, port, device = StartNachiEmulator("--duration", "20")
    try:
        link = NachiLink("mz04d", "127.0.0.1", port)
        collector = ToFLineCollector()
        transport = SerialTransport(collector, device, 115200)
        time.sleep(0.2)
        np.testing.assert_allclose(link.latest().q, HOME, atol=1e-4)
        (status,) = link.Request(nachi.STATUS)
        assert status == "STATUS IDLE 0 0"
        driver = ToFDriver(collector, period=0.02, watchdog=0.2)
        simulator = Simulator(driver)
        simulator.set_target_realtime_rate(1.0)
        simulator.AdvanceTo(0.1)
        ranges = driver.GetOutputPort("ranges").Eval(simulator.get_context())
        valid = driver.GetOutputPort("valid").Eval(simulator.get_context())
        transport.close()
        link.close()
    finally:
        StopServer(process)
    # At home nothing is within the sensors' 100 mm: every reading is "no return" (status
    # 11 on the line), reported as max_range like the simulated sensor. Readings of a hose
    # are compared end to end in the path-following hardware-in-the-loop test.
    station = MakeStation(DefaultCell())
    context = station.CreateDefaultContext()
    np.testing.assert_array_equal(valid, station.GetOutputPort("tof.valid").Eval(context))
    np.testing.assert_array_equal(ranges, station.GetOutputPort("tof.ranges").Eval(context))
    assert collector.accepted >= 4 and collector.rejected == 0


def test_tof_lines_leave_the_emulator_on_the_driver_timing_model():
    """Each ToF line of `emulate nachi` leaves `latency` (5 ms) after its range's end of
    ranging (k period on the controller clock), as the hardware ToFDriver assumes when it
    subtracts latency + ranging_time / 2 from the arrival to get `measured_at`. In lockstep
    the station stands still between SERVO targets, so after each target the lines written
    are exactly those due by the controller time READ_JOINTS reports, however the OS ran
    the processes (their arrival on the host clock is a benchmark:
    tests/benchmarks/bench_emulator_realtime.py)."""
    # The streaming timeout is the host clock's in lockstep: 5 s, as the wait below.
    process, port, device = StartNachiEmulator(
        "--duration", "20", "--lockstep", "--servo-timeout", "5"
    )
    collector = ToFLineCollector()
    transport = SerialTransport(collector, device, 115200)
    period, latency = ToFToolConfig().period, DEFAULT_TOF_LATENCY
    checked = []
    try:
        with socket.create_connection(("127.0.0.1", port)) as connection:
            replies = connection.makefile("r")
            for _ in range(100):  # 0.4 s of the controller clock in 4 ms targets
                servo = nachi.FormatServo(HOME, 0.004)
                connection.sendall(f"{servo}\nREAD_JOINTS\n".encode())
                assert replies.readline().strip() == "OK"
                controller_time = float(replies.readline().split()[1])
                newest = int(np.floor((controller_time - latency) / period + 1e-6))
                if newest >= 0:  # a line is due
                    checked.append((newest, _NewestSeq(collector, newest), controller_time))
    finally:
        transport.close()
        StopServer(process)
    newest_expected, newest_seen, _ = np.array(checked).T
    # every line due was written, none ahead of the controller clock (20 lines in 0.4 s)
    np.testing.assert_array_equal(newest_seen, newest_expected)
    assert newest_expected[-1] - newest_expected[0] >= 19 and collector.rejected == 0


def _NewestSeq(collector: ToFLineCollector, expected: int) -> int:
    """The sequence number of the collector's newest line once it has read line `expected`
    (already written to its pty; 5 s is a bound for a loaded machine, not a timing), or
    whatever came in those 5 s (-1: nothing). A line written ahead of the clock shows as
    newer than expected by the next target at the latest."""
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        latest = collector.latest()
        if latest is not None and latest[0].seq >= expected:
            break
        time.sleep(0.001)
    latest = collector.latest()
    return -1 if latest is None else latest[0].seq


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["nachi", "--scenario", "panel_operation", "--arm", "rover_arm"],
            "arm rover_arm: its model has no frame 'flange'",
        ),
        (["nachi", "--scenario", "marker_view"], "task 'marker_view' builds no station"),
        (["tof", "--scenario", "panel_operation"], "the station has no tof_tools to emulate"),
    ],
)
def test_scenarios_the_emulator_cannot_serve_are_refused_in_one_line(run_cli, args, message):
    code, out, err = run_cli("emulate", *args, "--duration", "1")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and message in err
