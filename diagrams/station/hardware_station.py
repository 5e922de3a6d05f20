"""MakeHardwareStation: the station's ports (without the sim-only `sim.` ones) served by
drivers of real arms, cameras and ToF tools, chosen in the scenario's `hardware` section.

The models of the scenario are still loaded: the arms' joint limits come from them, and
Meshcat draws the measured configuration. Hardware diagrams must run in real time:
`simulator.set_target_realtime_rate(1.0)`.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, SceneGraph
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain, Multiplexer
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from guidedarm.diagrams.station.hardware_config import ArmDriverConfig, UrRtdeDriver
from guidedarm.diagrams.station.link_checks import (
    CheckHardwareEntries,
    ProveCamera,
    ProveToFTool,
)
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import (
    AddStationModels,
    ArmCalibrationOffset,
    GetArmInstance,
    SetInitialPositions,
)
from guidedarm.diagrams.station.station_wiring import AddOffset
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import nachi_protocol
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.arm_link import ArmLink
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.hardware.nachi_link import NachiLink
from guidedarm.systems.hardware.opencv_camera import FrameGrabber, OpenCvCamera
from guidedarm.systems.hardware.tof_driver import ToFDriver
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector
from guidedarm.systems.hardware.ur_rtde_link import OpenUrRtde
from guidedarm.systems.tof.tof_tool_sensor import TOF_PORTS, MakeDetectionGrid

# The ToF driver looks for a new line this many times per ranging period: a line reaches
# the diagram within a fraction of a period, and two lines never fall into one update
# (the later would hide the earlier) unless the host stalls.
TOF_POLLS_PER_PERIOD = 4


# How far (rad) a hardware arm's joints may be from a task's start pose when a run begins:
# the first streamed command moves it there within one control period, which the command
# guard's acceleration limits allow only for jumps of about 1e-3 rad.
START_TOLERANCE = 1e-4


def MakeHardwareStation(scenario: StationScenario, meshcat: Meshcat | None = None) -> Diagram:
    """Builds the hardware station of `scenario`; connects to every configured device."""
    hardware = scenario.hardware
    CheckHardwareEntries(scenario, hardware)
    builder = DiagramBuilder()
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = MultibodyPlant(0.0)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    AddStationModels(scenario, plant)
    plant.Finalize()
    SetInitialPositions(scenario, plant)
    # The sensors prove themselves first: an arm connection sends RESET (docs/hardware.md).
    for name, camera in scenario.cameras.items():
        config = hardware.cameras[name]
        grabber = FrameGrabber(config.source)
        ProveCamera(name, grabber, camera.width, camera.height, config.watchdog)
        system = OpenCvCamera(
            grabber,
            camera.width,
            camera.height,
            1.0 / camera.fps,
            config.watchdog,
        )
        builder.AddNamedSystem(f"{name}.opencv_camera", system)
        builder.ExportOutput(system.get_output_port(), f"{name}.rgb_image")
    for name in scenario.tof_tools:
        tool = scenario.ToFTool(name)
        config = hardware.tof_tools[name]
        collector = ToFLineCollector(name)
        transport = config.Open(collector)
        ProveToFTool(collector, config.Where(), config.watchdog)
        grid = MakeDetectionGrid(plant, tool)
        latency = tool.ranging_time / 2 + config.latency
        system = ToFDriver(
            collector,
            tool.period / TOF_POLLS_PER_PERIOD,
            config.watchdog,
            tool.max_range,
            grid,
            latency=latency,
            calibration_offset=scenario.ToFCalibration(name),
            drain=config.Drain(transport),
        )
        builder.AddNamedSystem(f"{name}.driver", system)
        for port in TOF_PORTS:
            builder.ExportOutput(system.GetOutputPort(port), f"{name}.{port}")
    measured: dict[str, OutputPort] = {}
    for name, arm in scenario.arms.items():
        config = hardware.arms[name]
        instance = GetArmInstance(plant, name)
        try:
            limits = JointLimits.FromPlant(plant, instance, config.acceleration_limits)
        except ConfigurationError as e:
            raise ConfigurationError(f"hardware.arms.{name}.acceleration_limits: {e}") from None
        driver = builder.AddNamedSystem(
            f"{name}.driver",
            ArmDriver(
                _OpenArmLink(name, config, arm.control_period),
                limits,
                arm.control_period,
                config.watchdog,
                config.stale_after,
            ),
        )
        ports = {p: driver.GetOutputPort(p) for p in ("position_measured", "state_estimated")}
        command = driver.get_input_port()
        n = command.size()
        calibration = ArmCalibrationOffset(scenario, name, n)
        if calibration is not None:
            # The driver speaks the arm's own joint angles; the ports calibrated ones.
            to_arm = AddOffset(builder, f"{name}.command_calibration", -calibration)
            builder.Connect(to_arm.get_output_port(), command)
            command = to_arm.get_input_port()
            offsets = {"position_measured": calibration}
            offsets["state_estimated"] = np.concatenate([calibration, np.zeros(n)])
            for port, offset in offsets.items():
                calibrated = AddOffset(builder, f"{name}.{port}_calibration", offset)
                builder.Connect(ports[port], calibrated.get_input_port())
                ports[port] = calibrated.get_output_port()
        ports["velocity_estimated"] = driver.GetOutputPort("velocity_estimated")
        builder.ExportInput(command, f"{name}.position_commanded")
        for port, output in ports.items():
            builder.ExportOutput(output, f"{name}.{port}")
        measured[name] = ports["position_measured"]
    if meshcat is not None:
        _DrawMeasured(builder, plant, scene_graph, measured, meshcat)
    diagram = builder.Build()
    diagram.set_name("hardware_station")
    return diagram


def _OpenArmLink(name: str, config: ArmDriverConfig, period: float) -> ArmLink:
    if isinstance(config, UrRtdeDriver):
        return OpenUrRtde(
            name,
            config.host,
            config.lookahead_time,
            config.gain,
            config.servo_timeout,
            lockstep_wait=config.watchdog if config.lockstep else None,
        )
    port = config.port or nachi_protocol.DEFAULT_PORT
    return NachiLink(
        name,
        config.host,
        port,
        poll_period=period,
        command_mode=config.command_mode,
        lockstep_wait=config.watchdog if config.lockstep else None,
    )


def _DrawMeasured(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    measured: dict[str, OutputPort],
    meshcat: Meshcat,
) -> None:
    """Meshcat shows the plant at the measured arm joints (other joints at their defaults):
    q_plant = P [q_arm_1; ...; q_arm_k; q_default]."""
    nq = plant.num_positions()
    q_default = plant.GetPositions(plant.CreateDefaultContext())
    rows = [_PositionRows(plant, name) for name in measured]
    sizes = [len(r) for r in rows] + [nq]
    P = np.zeros((nq, sum(sizes)))
    column = 0
    for r in rows:
        P[r, column : column + len(r)] = np.eye(len(r))
        column += len(r)
    arm_rows = np.concatenate(rows) if rows else np.zeros(0, int)
    rest = np.setdiff1d(np.arange(nq), arm_rows)
    P[rest, column + rest] = 1.0
    mux = builder.AddNamedSystem("measured_mux", Multiplexer(sizes))
    for i, port in enumerate(measured.values()):
        builder.Connect(port, mux.get_input_port(i))
    default = builder.AddNamedSystem("default_positions", ConstantVectorSource(q_default))
    builder.Connect(default.get_output_port(), mux.get_input_port(len(rows)))
    gain = builder.AddNamedSystem("plant_positions", MatrixGain(P))
    to_pose = builder.AddNamedSystem("to_pose", MultibodyPositionToGeometryPose(plant))
    builder.Connect(mux.get_output_port(), gain.get_input_port())
    builder.Connect(gain.get_output_port(), to_pose.get_input_port())
    builder.Connect(
        to_pose.get_output_port(), scene_graph.get_source_pose_port(plant.get_source_id())
    )
    MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)


def _PositionRows(plant: MultibodyPlant, name: str) -> np.ndarray:
    """Indices of the instance's positions in the plant's position vector."""
    every = np.arange(plant.num_positions(), dtype=float)
    return plant.GetPositionsFromArray(plant.GetModelInstanceByName(name), every).astype(int)
