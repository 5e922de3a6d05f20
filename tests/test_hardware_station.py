"""MakeStation(kind="hardware") exports the same ports as the simulated station."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest
from hardware_doubles import RELAXED_SERVO_TIMEOUT, Mz04dScenario, WriteTestVideo
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.station.hardware_config import (
    HardwareConfig,
    NachiDriver,
    OpenCvCameraDriver,
    ToFSerialDriver,
    UrRtdeDriver,
)
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.nachi_emulator import NachiEmulator
from guidedarm.systems.hardware.tof_emulator import ToFEmulator
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig


def _Ports(diagram) -> dict[str, object]:
    """Port name -> vector size, or image width x height for image ports."""

    def describe(port):
        if port.get_data_type().name == "kVectorValued":
            return port.size()
        value = port.Allocate() if hasattr(port, "Allocate") else None
        image = value.get_value() if isinstance(value, AbstractValue) else None
        return (image.width(), image.height()) if image is not None else "abstract"

    ports = {}
    for i in range(diagram.num_input_ports()):
        port = diagram.get_input_port(i)
        ports[f"in:{port.get_name()}"] = describe(port)
    for i in range(diagram.num_output_ports()):
        port = diagram.get_output_port(i)
        if not port.get_name().startswith("sim."):
            ports[f"out:{port.get_name()}"] = describe(port)
    return ports


@pytest.fixture
def devices(tmp_path):
    station = MakeStation(Mz04dScenario())
    emulator = NachiEmulator(station, "mz04d", port=0, servo_timeout=RELAXED_SERVO_TIMEOUT)
    thread = threading.Thread(target=emulator.Run, kwargs={"duration": 30.0}, daemon=True)
    thread.start()
    tof = ToFEmulator(lambda: (np.full(6, 0.05), np.zeros(6, int)), period=0.02)
    video = tmp_path / "camera.avi"
    WriteTestVideo(video, 64, 48, 30.0, 10)
    yield emulator.port, tof.device, str(video)
    emulator.Close()
    tof.close()


def test_sim_and_hardware_stations_export_the_same_ports(devices):
    nachi_port, tof_device, video = devices
    camera = CameraConfig(width=64, height=48, fps=10.0)
    hardware = HardwareConfig(
        arms={"mz04d": NachiDriver(port=nachi_port, acceleration_limits=[20.0] * 6)},
        cameras={"camera": OpenCvCameraDriver(source=video)},
        tof_tools={"tof": ToFSerialDriver(device=tof_device)},
    )
    scenario = Mz04dScenario(
        cameras={"camera": camera}, tof_tools={"tof": ToFToolConfig()}, hardware=hardware
    )
    sim = _Ports(MakeStation(scenario))
    real = _Ports(MakeStation(scenario, kind="hardware"))
    assert real == sim
    assert real["out:mz04d.state_estimated"] == 12
    assert real["out:camera.rgb_image"] == (64, 48)
    assert real["out:tof.ranges"] == 6 and real["out:tof.valid"] == 6


def test_station_without_a_driver_for_an_arm_fails_before_connecting():
    with pytest.raises(ConfigurationError, match=r"hardware.arms: no driver for \['mz04d'\]"):
        MakeStation(Mz04dScenario(), kind="hardware")


def test_a_driver_of_another_device_is_named():
    hardware = HardwareConfig(arms={"mz04d": OpenCvCameraDriver()})
    expected = r"hardware\.arms\.mz04d': expected UrRtdeDriver or NachiDriver, got OpenCv"
    with pytest.raises(ConfigurationError, match=expected):
        MakeStation(Mz04dScenario(hardware=hardware), kind="hardware")


def test_meshcat_draws_the_measured_configuration(devices):
    nachi_port, _, _ = devices
    arm = NachiDriver(port=nachi_port, watchdog=0.5, acceleration_limits=[20.0] * 6)
    scenario = Mz04dScenario(hardware=HardwareConfig(arms={"mz04d": arm}))
    meshcat = Meshcat()
    station = MakeStation(scenario, meshcat, kind="hardware")
    simulator = Simulator(station)
    station.GetInputPort("mz04d.position_commanded").FixValue(
        simulator.get_mutable_context(), [0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0]
    )
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(0.2)
    # The plant's position vector seen by Meshcat: the arm's joints at their measured values.
    context = simulator.get_context()
    plant_positions = station.GetSubsystemByName("plant_positions")
    positions = plant_positions.get_output_port().Eval(
        plant_positions.GetMyContextFromRoot(context)
    )
    measured = station.GetOutputPort("mz04d.position_measured").Eval(context)
    np.testing.assert_allclose(positions[:6], measured)
    assert meshcat.HasPath("/drake/visualizer/mz04d")


LIMITS = {"acceleration_limits": [10.0] * 6}


@pytest.mark.parametrize(
    "driver, arm, tof, message",
    [
        (
            NachiDriver,
            {"port": 70000},
            {},
            r"arms\.mz04d\.port': must be in \[0, 65535\], got 70000",
        ),
        (NachiDriver, {"port": -1}, {}, r"arms\.mz04d\.port': must be in \[0, 65535\], got -1"),
        (NachiDriver, {"host": " "}, {}, r"arms\.mz04d\.host': must not be empty"),
        (NachiDriver, {"watchdog": float("nan")}, {}, r"arms\.mz04d\.watchdog': must be a finite"),
        (NachiDriver, {"watchdog": 0.0}, {}, r"arms\.mz04d\.watchdog': must be > 0, got 0\.0"),
        (NachiDriver, {"stale_after": 0.6}, {}, r"arms\.mz04d\.stale_after': 0\.6 s exceeds"),
        (
            NachiDriver,
            {"acceleration_limits": [1.0] * 5 + [float("inf")]},
            {},
            r"arms\.mz04d\.acceleration_limits\[5\]': must be a finite number, got inf",
        ),
        (UrRtdeDriver, {"gain": 5000.0}, {}, r"arms\.mz04d\.gain': must be in \[100, 2000\]"),
        (
            NachiDriver,
            {"command_mode": "servo"},
            {},
            r"arms\.mz04d\.command_mode': 'servo' is not one of 'stream', 'move'",
        ),
        (UrRtdeDriver, {"lookahead_time": float("nan")}, {}, r"arms\.mz04d\.lookahead_time'"),
        (NachiDriver, {}, {"device": ""}, r"tof_tools\.tof\.device': must not be empty"),
        (NachiDriver, {}, {"watchdog": -1.0}, r"tof_tools\.tof\.watchdog': must be > 0, got -1"),
    ],
)
def test_bad_driver_settings_are_refused_before_connecting(driver, arm, tof, message):
    hardware = HardwareConfig(
        arms={"mz04d": driver(**{**LIMITS, **arm})},
        tof_tools={"tof": ToFSerialDriver(**{"device": "/dev/null", **tof})},
    )
    scenario = Mz04dScenario(hardware=hardware, tof_tools={"tof": ToFToolConfig()})
    with pytest.raises(ConfigurationError, match=f"^key 'scenario\\.hardware\\.{message}"):
        MakeStation(scenario, kind="hardware")


def test_unreachable_nachi_controller_is_refused_before_the_run():
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]  # bound, closed below: nothing listens there
    hardware = HardwareConfig(arms={"mz04d": NachiDriver(**LIMITS, port=port)})
    with pytest.raises(ConfigurationError, match=f"mz04d: cannot reach 127.0.0.1:{port}: "):
        MakeStation(Mz04dScenario(hardware=hardware), kind="hardware")
