"""ToF tool driver: the line parser, byte-stream assembly (serial reads, BLE notifications),
and the whole path through a pseudo-terminal fed by the emulator."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
from hardware_doubles import LOADED_MACHINE_BOUND, WaitUntil
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator

from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.tof_driver import ToFDriver
from guidedarm.systems.hardware.tof_emulator import ToFEmulator
from guidedarm.systems.hardware.tof_protocol import (
    Checksum,
    FormatTofLine,
    ParseTofLine,
    ToFLineCollector,
    ToFLineError,
)
from guidedarm.systems.hardware.tof_transports import BleTransport, SerialTransport
from guidedarm.systems.tof.detection_grid import DetectionGrid

RANGES_MM = np.array([12, 40, 100, 255, 0, 73])
GRID = (-0.022, 0.0, 0.022)
STATUS = np.array([0, 0, 0, 15, 12, 0])
GOOD = FormatTofLine(7, RANGES_MM, STATUS)


def test_line_round_trip_and_validity():
    reading = ParseTofLine(GOOD + "\r\n")
    assert reading.seq == 7
    np.testing.assert_allclose(reading.ranges, 1e-3 * RANGES_MM)
    np.testing.assert_array_equal(reading.valid, [1, 1, 1, 0, 0, 1])


@pytest.mark.parametrize(
    "line, message",
    [
        (GOOD[:30], "not a ToF line"),
        (GOOD[:-2] + "00", "checksum mismatch"),
        (FormatTofLine(1, [300, 0, 0, 0, 0, 0], [0] * 6), "range outside"),
        (FormatTofLine(1, [1] * 6, [9, 0, 0, 0, 0, 0]), "unknown VL6180X status code 9"),
        (FormatTofLine(1, [1] * 5, [0] * 5), "11 fields, expected 13"),
        (f"$TOF,1,a*{Checksum('TOF,1,a'):02X}", "not an integer"),
    ],
)
def test_malformed_lines_are_rejected_with_the_cause(line, message):
    with pytest.raises(ToFLineError, match=message):
        ParseTofLine(line)


def test_collector_assembles_ble_sized_chunks_and_counts_rejects(capsys):
    lines = [FormatTofLine(i, RANGES_MM, STATUS) + "\r\n" for i in range(10)]
    lines[3] = lines[3][:25]  # cut short: the next line starts right after it
    lines[6] = lines[6].replace(",40,", ",41,")  # corrupted: checksum no longer matches
    stream = "".join(lines).encode()
    collector = ToFLineCollector()
    for i in range(0, len(stream), 20):  # BLE notifications carry at most 20 bytes
        collector.Feed(stream[i : i + 20])
    assert (collector.accepted, collector.rejected) == (8, 2)
    assert collector.latest()[0].seq == 9
    assert "truncated line" in capsys.readouterr().out


def test_ble_transport_without_adapter_fails_with_one_line():
    with pytest.raises(ConfigurationError, match="tof: cannot connect BLE device"):
        BleTransport(ToFLineCollector(), "00:11:22:33:44:55")


def _Grid() -> DetectionGrid:
    """The tool's geometry: row sensors 55 mm above the centre looking down, column sensors
    55 mm to the side looking across, 22 mm apart."""
    rows = [RigidTransform(RotationMatrix.MakeXRotation(np.pi), [0, y, 0.055]) for y in GRID]
    columns = [
        RigidTransform(RotationMatrix.MakeXRotation(-np.pi / 2), [0, -0.055, z]) for z in GRID
    ]
    return DetectionGrid((*rows, *columns), 0.010)


def _Source():
    return 1e-3 * RANGES_MM, STATUS


def test_driver_reads_the_emulator_through_a_pty_and_survives_bad_lines():
    emulator = ToFEmulator(_Source, period=0.01, corrupt_every=5)
    collector = ToFLineCollector()
    transport = SerialTransport(collector, emulator.device, 115200)
    try:
        # The watchdog is not this test's subject: one a loaded machine cannot trip.
        driver = ToFDriver(collector, 0.02, LOADED_MACHINE_BOUND, no_return_range=0.1, grid=_Grid())
        assert WaitUntil(lambda: collector.accepted > 0)
        simulator = Simulator(driver)
        simulator.set_target_realtime_rate(1.0)
        simulator.AdvanceTo(0.5)
        context = simulator.get_context()
        expected = np.where(STATUS == 0, 1e-3 * RANGES_MM, 0.1)  # as the simulated sensor
        np.testing.assert_allclose(driver.GetOutputPort("ranges").Eval(context), expected)
        np.testing.assert_array_equal(driver.GetOutputPort("valid").Eval(context), STATUS == 0)
        # The paper's grid of that reading, as the simulated sensor outputs it.
        detected, errors = _Grid().Detect(expected, STATUS == 0)
        for port, grid in (("detections", detected), ("detection_errors", errors)):
            np.testing.assert_array_equal(driver.GetOutputPort(port).Eval(context), grid.ravel())
        assert detected.sum() == 3  # rows 1-3 x column 6 (sensors 4, 5 invalid)
    finally:
        emulator.close()
        time.sleep(0.05)
        transport.close()
    # Opening the port flushes what the emulator wrote before (a line or two), and the last
    # truncated line may still wait for the next start to be rejected.
    corrupted = emulator.lines // 5
    assert corrupted - 2 <= collector.rejected <= corrupted
    assert emulator.lines - corrupted - 4 <= collector.accepted <= emulator.lines - corrupted


def test_silent_tool_fails_the_run_after_its_watchdog():
    emulator = ToFEmulator(_Source, period=0.01)
    collector = ToFLineCollector()
    transport = SerialTransport(collector, emulator.device, 115200)
    # Long enough that the streaming tool never trips it on a loaded machine; the silence
    # after the tool stops must.
    watchdog = 1.0
    driver = ToFDriver(collector, period=0.02, watchdog=watchdog)
    simulator = Simulator(driver)
    simulator.set_target_realtime_rate(1.0)
    try:
        assert WaitUntil(lambda: collector.accepted > 0)
        simulator.AdvanceTo(0.2)
        emulator.close()
        start = time.monotonic()
        with pytest.raises(
            HardwareFaultError, match=r"on tof at t = \d\.\d+ s: no valid line for \d\.\d+ s"
        ) as fault:
            simulator.AdvanceTo(10.0)
        # After the watchdog, well before the 10 s the run asked for.
        silent_for = float(re.search(r"no valid line for (\S+) s", str(fault.value))[1])
        assert silent_for >= watchdog
        assert time.monotonic() - start < watchdog + LOADED_MACHINE_BOUND
    finally:
        emulator.close()
        transport.close()


def test_driver_stamps_a_line_with_its_measurement_instant_in_diagram_time():
    """A line that arrived 30 ms (host clock) before the update at diagram time 5 s, with
    7 ms from measurement to arrival, was measured at 5 - 0.030 - 0.007 s; the stamp is
    kept while the same line is held, and a new line gets its own; -1 before any line."""
    collector = ToFLineCollector()
    driver = ToFDriver(collector, period=0.02, watchdog=1.0, latency=0.007)
    context = driver.CreateDefaultContext()
    stamp = driver.GetOutputPort("measured_at")
    np.testing.assert_array_equal(stamp.Eval(context), np.full(6, -1.0))
    collector.Feed((GOOD + "\r\n").encode())
    received = collector.latest()[1]
    time.sleep(0.03)
    context.SetTime(5.0)
    before = time.monotonic()
    context.SetDiscreteState(driver.EvalUniquePeriodicDiscreteUpdate(context).value())
    after = time.monotonic()
    measured_at = stamp.Eval(context)
    assert np.ptp(measured_at) == 0.0
    assert 5.0 - (after - received) - 0.007 <= measured_at[0] <= 5.0 - (before - received) - 0.007
    assert measured_at[0] <= 5.0 - 0.030 - 0.007
    context.SetTime(5.02)
    context.SetDiscreteState(driver.EvalUniquePeriodicDiscreteUpdate(context).value())
    np.testing.assert_array_equal(stamp.Eval(context), measured_at)
    collector.Feed((FormatTofLine(8, RANGES_MM, STATUS) + "\r\n").encode())
    received = collector.latest()[1]
    context.SetTime(5.04)
    before = time.monotonic()
    context.SetDiscreteState(driver.EvalUniquePeriodicDiscreteUpdate(context).value())
    after = time.monotonic()
    newer = stamp.Eval(context)[0]
    assert 5.04 - (after - received) - 0.007 <= newer <= 5.04 - (before - received) - 0.007


def test_each_line_is_stamped_when_it_arrives():
    """Lines written 10 ms apart each keep their own receive time, the basis of
    `measured_at`: the serial transport hands over the bytes that arrived, not fixed-size
    chunks (a read of 256 bytes waited up to its 50 ms timeout and stamped 2-3 lines with
    one late time). Each line is written once the one before was received, so every line is
    seen; each stamp lies between its own write and the next line's; the median delay is
    far below the 50 ms that chunked reading gives every line (0.4 ms measured; a loaded
    machine delays a few lines, not the median)."""
    emulator = ToFEmulator(None)
    collector = ToFLineCollector()
    transport = SerialTransport(collector, emulator.device, 115200)
    written, stamps = [], []

    def Received(seq: int) -> bool:
        latest = collector.latest()
        return latest is not None and latest[0].seq == seq

    try:
        for k in range(50):
            time.sleep(0.01)
            written.append(time.monotonic())
            emulator.Write(np.full(6, 0.001 * k), STATUS)
            assert WaitUntil(lambda k=k: Received(k))
            stamps.append(collector.latest()[1])
    finally:
        emulator.close()
        transport.close()
    delays = np.array(stamps) - np.array(written)
    print(
        f"delay median {1e3 * np.median(delays):.2f} ms, p90 "
        f"{1e3 * np.percentile(delays, 90):.2f} ms, max {1e3 * delays.max():.2f} ms"
    )
    assert np.all(delays >= 0) and np.all(np.array(stamps[:-1]) < written[1:])
    assert np.median(delays) < 0.025


def test_driver_subtracts_the_calibrated_offsets_from_valid_ranges():
    """The ToF tool's calibration_file offsets leave the driver's valid ranges shorter by
    them; an invalid sensor keeps the no-return range."""
    collector = ToFLineCollector()
    offset = np.array([0.001, -0.002, 0.003, 0.0, 0.004, -0.001])
    driver = ToFDriver(collector, 0.02, 10.0, no_return_range=0.1, calibration_offset=offset)
    collector.Feed((GOOD + "\r\n").encode())
    simulator = Simulator(driver)
    simulator.AdvanceTo(0.05)
    ranges = driver.GetOutputPort("ranges").Eval(simulator.get_context())
    expected = np.where(STATUS == 0, 1e-3 * RANGES_MM - offset, 0.1)
    np.testing.assert_allclose(ranges, expected)


def test_in_lockstep_each_update_reads_the_line_written_before_it():
    """With `drain` (a lockstep ToFSerialDriver), the reading at an update is the newest line
    written before it, however late the transport's thread runs: each line is written right
    before the update, faster than the thread could be scheduled to read it (without the
    drain the driver holds the previous line). Its stamp is the update's time minus the
    latency, exactly."""
    emulator = ToFEmulator(None)
    collector = ToFLineCollector()
    transport = SerialTransport(collector, emulator.device, 115200)
    driver = ToFDriver(collector, 0.01, 5.0, latency=0.007, drain=transport.Drain)
    context = driver.CreateDefaultContext()
    try:
        for k in range(20):
            emulator.Write(np.full(6, 0.001 * (k + 1)), np.zeros(6))
            context.SetTime(0.01 * k)
            context.SetDiscreteState(driver.EvalUniquePeriodicDiscreteUpdate(context).value())
            ranges = driver.GetOutputPort("ranges").Eval(context)
            np.testing.assert_array_equal(ranges, np.full(6, 0.001 * (k + 1)))
            measured_at = driver.GetOutputPort("measured_at").Eval(context)
            np.testing.assert_array_equal(measured_at, np.full(6, 0.01 * k - 0.007))
    finally:
        emulator.close()
        transport.close()
