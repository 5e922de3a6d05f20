"""AddPanelOperation and the controller plant of the camera arm (the panel task's builder)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.schema import Rotation, Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.panel_operation.builder import (
    AddPanelOperation,
    MakeCameraArmKinematics,
)
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.panel.panel_operation_math import PanelOperationConfig

ARM, CAMERA, TIP = "rover_arm", "camera", "rover_gripper::gripper_tip"


def _station_scenario():
    _, scenario, _ = LoadScenario("panel_operation", [])
    return scenario.station


@pytest.mark.parametrize("offset", [False, True])
def test_controller_kinematics_match_the_station(offset):
    """Camera and tip poses of the controller plant (the arm and gripper only, the rover's
    weld replaced by a weld to the world) equal the station's at random joint positions,
    including a camera moved by X_PB and X_BC."""
    station_scenario = _station_scenario()
    camera = station_scenario.cameras[CAMERA]
    if offset:
        camera.X_PB = Transform(RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.01, 0.02, 0.03]))
        camera.X_PB.base_frame = "rover_gripper::camera"
        camera.X_BC = Transform(translation=[0.0, 0.004, 0.0], rotation=Rotation())
    kinematics = MakeCameraArmKinematics(station_scenario, ARM, CAMERA, TIP)
    assert kinematics.plant.num_positions() == 6
    station = MakeStation(station_scenario)
    context = station.CreateDefaultContext()
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyMutableContextFromRoot(context)
    tip = plant.GetFrameByName("gripper_tip", plant.GetModelInstanceByName("rover_gripper"))
    X_BC = camera.X_BC.GetDeterministicValue()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 6)
        plant.SetPositions(plant_context, plant.GetModelInstanceByName(ARM), q)
        X_WS = station.GetOutputPort(f"sim.{CAMERA}.X_WS").Eval(context)
        assert kinematics.X_WC(q).IsNearlyEqualTo(X_WS @ X_BC, 1e-12)
        assert kinematics.X_WT(q).IsNearlyEqualTo(tip.CalcPoseInWorld(plant_context), 1e-12)


def _add(builder=None, **kwargs):
    station_scenario = _station_scenario()
    builder = builder or DiagramBuilder()
    station = builder.AddSystem(MakeStation(station_scenario))
    arguments = {"arm": ARM, "camera": CAMERA, "tip_frame": TIP, **kwargs}
    panel = LoadPanelSpec(DEFAULT_PANEL_FILE)
    switch = arguments.pop("switch", 2)
    return AddPanelOperation(builder, station, station_scenario, panel, switch, **arguments)


def test_drives_the_station_command_from_the_camera_image():
    builder = DiagramBuilder()
    systems = _add(builder)
    assert systems.degradation is None and systems.planner is None
    diagram = builder.Build()
    # every input is connected: the station's arm command and the sequencer's two inputs
    assert diagram.num_input_ports() == 0
    context = diagram.CreateDefaultContext()
    sequencer_context = systems.sequencer.GetMyContextFromRoot(context)
    q_home = systems.kinematics.plant.GetPositions(systems.kinematics.plant.CreateDefaultContext())
    np.testing.assert_allclose(
        systems.sequencer.GetInputPort("arm_state").Eval(sequencer_context)[:6], q_home
    )
    estimate = systems.sequencer.GetInputPort("marker_estimate").Eval(sequencer_context)
    assert estimate.valid and sorted(estimate.ids) == [7, 42]
    # the estimate against the truth: X_CP = X_WC(q)^-1 X_WP, 201 mm in front at home
    plant = diagram.GetSubsystemByName("station").GetSubsystemByName("plant")
    X_WP = plant.GetFrameByName("plate", plant.GetModelInstanceByName("panel")).CalcPoseInWorld(
        plant.GetMyContextFromRoot(context)
    )
    X_CP = systems.kinematics.X_WC(q_home).inverse() @ X_WP
    assert abs(X_CP.translation()[2] - 0.201) < 0.001
    assert np.linalg.norm(estimate.X_CP.translation() - X_CP.translation()) < 0.001


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"switch": 4}, "switch must be 1 .. 3, got 4"),
        ({"arm": "ur10e"}, "arm 'ur10e' is not in station.arms"),
        ({"camera": "webcam"}, "camera 'webcam' is not in station.cameras"),
        ({"tip_frame": "gripper_tip"}, "tip_frame: 'gripper_tip' must be a scoped frame"),
        ({"tip_frame": "rover_gripper::nose"}, "tip_frame: no frame 'rover_gripper::nose'"),
        (
            {"operation": PanelOperationConfig(motion="planner")},
            'an AccelerationPlanner is needed exactly when operation.motion is "planner"',
        ),
    ],
)
def test_bad_arguments_are_refused_in_one_line(kwargs, message):
    with pytest.raises(ConfigurationError) as error:
        _add(**kwargs)
    assert message in str(error.value) and "\n" not in str(error.value)
