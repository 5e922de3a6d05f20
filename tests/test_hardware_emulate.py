"""`guidedarm emulate nachi`: a separate process serving the MZ04D over TCP and the ToF tool
over a pseudo-terminal, read back with the project's own drivers."""

from __future__ import annotations

import time

import numpy as np
from hardware_doubles import StartNachiEmulator, StopServer
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.cli.command_emulate import DefaultCell
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.nachi_link import NachiLink
from guidedarm.systems.hardware.tof_driver import ToFDriver
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector
from guidedarm.systems.hardware.tof_transports import SerialTransport

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
