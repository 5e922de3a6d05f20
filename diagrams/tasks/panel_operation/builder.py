"""AddPanelOperation: the marker-guided switch pressing of Annusewicz-Mistal et al.,
"Autonomous Manipulator of a Mobile Robot Based on a Vision System" (Appl. Sci. 2023),
added to a station's diagram.

Data path, all inside one DiagramBuilder:

    station `<camera>.rgb_image` -> [ImageDegradation] -> MarkerPoseEstimator
        -> PanelOperation (also reads `<arm>.state_estimated`)
        -> station `<arm>.position_commanded`
           (or PanelOperation -> AccelerationPlanner -> `<arm>.position_commanded`)

The sequencer's kinematics (camera pose X_WC(q), tip pose X_WT(q), tip IK) run on the
controller plant `MakeMultibodyPlant(station_scenario, [arm, camera's and tip's model
instances])`: the arm as the station places it, without the panel.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, System

from guidedarm.diagrams.builder_checks import CheckStationWiring
from guidedarm.diagrams.panel.panel_files import IntrinsicsFromCameraConfig
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.systems.config_checks import CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig, ImageDegradation
from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
from guidedarm.systems.markers.marker_pose_estimator_math import (
    CameraIntrinsics,
    MarkerPoseSolver,
    PanelSpec,
)
from guidedarm.systems.panel.panel_operation import PanelOperation
from guidedarm.systems.panel.panel_operation_math import (
    CameraArmKinematics,
    PanelOperationConfig,
    PlannerFrames,
)
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.plant_frames import GetScopedFrame


@dataclass
class PanelOperationSystems:
    """The systems AddPanelOperation added (for logs and ground-truth evaluation).

    sequencer: the PanelOperation (its state: `sequencer.GetSequencerState(context)`).
    estimator: the MarkerPoseEstimator; degradation: the ImageDegradation, or None.
    kinematics: the controller plant's camera and tip kinematics the sequencer uses.
    planner: the AccelerationPlanner between sequencer and station, or None.
    """

    sequencer: PanelOperation
    estimator: MarkerPoseEstimator
    degradation: ImageDegradation | None
    kinematics: CameraArmKinematics
    planner: AccelerationPlanner | None


def MakeCameraArmKinematics(
    station_scenario: StationScenario,
    arm: str,
    camera: str,
    tip_frame: str,
    X_FC: RigidTransform | None = None,
) -> CameraArmKinematics:
    """Camera and tip kinematics of `arm` on its controller plant.

    camera: a key of station_scenario.cameras, whose X_PB.base_frame is a scoped frame on
    the arm's side (e.g. `rover_gripper::camera`); the camera frame C is that frame moved
    by the CameraConfig's X_PB and X_BC (Drake's and OpenCV's optical frame: x right, y
    down, z forward). tip_frame: the scoped frame T that presses (e.g.
    `rover_gripper::gripper_tip`). The plant holds only the model instances of the arm, the
    camera frame and the tip frame (the station's welds to dropped parents become welds to
    the world), so its positions are the arm's joints (rad).
    """
    if arm not in station_scenario.arms:
        raise ConfigurationError(f"arm '{arm}' is not in station.arms")
    if camera not in station_scenario.cameras:
        raise ConfigurationError(f"camera '{camera}' is not in station.cameras")
    config = station_scenario.cameras[camera]
    camera_frame = config.X_PB.base_frame or ""
    names = [arm]
    for key, scoped in (
        (f"cameras.{camera}.X_PB.base_frame", camera_frame),
        ("tip_frame", tip_frame),
    ):
        instance = scoped.rpartition("::")[0]
        if not instance:
            raise ConfigurationError(
                f"{key}: '{scoped}' must be a scoped frame (instance::frame) on the arm's side"
            )
        names.append(instance)
    plant = MakeMultibodyPlant(station_scenario, list(dict.fromkeys(names)))
    arm_joints = plant.num_positions(plant.GetModelInstanceByName(arm))
    if plant.num_positions() != arm_joints:
        raise ConfigurationError(
            f"the camera and tip must be welded to arm '{arm}' (the controller plant has "
            f"{plant.num_positions()} positions, the arm {arm_joints})"
        )
    if X_FC is None:
        X_FC = config.X_PB.GetDeterministicValue() @ config.X_BC.GetDeterministicValue()
    CheckInstance("X_FC", X_FC, RigidTransform)
    return CameraArmKinematics(
        plant,
        GetScopedFrame(plant, camera_frame, f"cameras.{camera}.X_PB.base_frame"),
        GetScopedFrame(plant, tip_frame, "tip_frame"),
        X_FC,
    )


def AddPanelOperation(
    builder: DiagramBuilder,
    station: System,
    station_scenario: StationScenario,
    panel: PanelSpec,
    switch: int,
    *,
    arm: str,
    camera: str,
    tip_frame: str,
    operation: PanelOperationConfig | None = None,
    degradation: DegradationConfig | None = None,
    intrinsics: CameraIntrinsics | None = None,
    planner: tuple[AccelerationPlanner, PlannerFrames] | None = None,
    camera_mount: RigidTransform | None = None,
) -> PanelOperationSystems:
    """Adds the panel operation to `builder` and connects it to `station`.

    station: a system of `builder` made by MakeStation(station_scenario) (simulated or
    hardware); it must export `<camera>.rgb_image` (ImageRgba8U), `<arm>.state_estimated`
    ([q; v], rad, rad/s) and `<arm>.position_commanded` (rad), which this drives.
    panel: the markers and switches (PANEL.yaml, frame P = the left marker's frame);
    switch: 1-based index into panel.switches. arm, camera, tip_frame: see
    MakeCameraArmKinematics. operation: the sequence's parameters (default
    PanelOperationConfig()). degradation: an ImageDegradation between camera and estimator
    (for rendered images; its `supersampling` k averages k x k pixel blocks, so the
    station's camera must render k times the wanted resolution); None feeds the camera's
    image straight to the estimator (hardware). intrinsics: of the image the estimator
    sees; default: those of the station's rendered camera reduced by k (VTK's pixel
    centres). planner: an AccelerationPlanner made with `accept_tasks=True` and its
    frames, required when operation.motion is "planner"; the sequencer then sends each
    move as a task and the planner streams the arm's commands. camera_mount: the camera
    frame C in the frame its X_PB names, as the controller believes it (e.g. a calibrated
    hand_eye.yaml's X_PC); default: the camera's X_PB X_BC.
    """
    CheckInstance("station_scenario", station_scenario, StationScenario)
    CheckInstance("panel", panel, PanelSpec)
    if isinstance(switch, bool) or not isinstance(switch, numbers.Integral):
        raise FieldError("switch", f"expected int, got {switch!r}")
    for key, value in (("arm", arm), ("camera", camera), ("tip_frame", tip_frame)):
        CheckInstance(key, value, str)
    for key, value, expected in (
        ("operation", operation, PanelOperationConfig),
        ("degradation", degradation, DegradationConfig),
        ("intrinsics", intrinsics, CameraIntrinsics),
        ("planner", planner, tuple),
    ):
        CheckInstance(key, value, (expected, type(None)))
    operation = operation or PanelOperationConfig()
    if not 1 <= switch <= len(panel.switches):
        raise ConfigurationError(f"switch must be 1 .. {len(panel.switches)}, got {switch}")
    if (operation.motion == "planner") != (planner is not None):
        raise ConfigurationError(
            'an AccelerationPlanner is needed exactly when operation.motion is "planner"'
        )
    kinematics = MakeCameraArmKinematics(station_scenario, arm, camera, tip_frame, camera_mount)
    CheckStationWiring(
        builder,
        station,
        inputs=[f"{arm}.position_commanded"],
        outputs=[f"{camera}.rgb_image", f"{arm}.state_estimated"],
        new_systems=["marker_pose_estimator", "panel_operation"]
        + ["image_degradation"] * (degradation is not None)
        + ["planner"] * (planner is not None),
    )
    k = degradation.supersampling if degradation is not None else 1
    if intrinsics is None:
        intrinsics = IntrinsicsFromCameraConfig(station_scenario.cameras[camera], k)
    image = station.GetOutputPort(f"{camera}.rgb_image")
    degrade = None
    if degradation is not None:
        degrade = builder.AddNamedSystem("image_degradation", ImageDegradation(degradation))
        builder.Connect(image, degrade.get_input_port())
        image = degrade.get_output_port()
    estimator = builder.AddNamedSystem(
        "marker_pose_estimator", MarkerPoseEstimator(MarkerPoseSolver(intrinsics, panel))
    )
    builder.Connect(image, estimator.get_input_port())
    planner_system, frames = planner if planner is not None else (None, None)
    sequencer = builder.AddNamedSystem(
        "panel_operation",
        PanelOperation(kinematics, panel, panel.switches[switch - 1], operation, frames),
    )
    arm_state = station.GetOutputPort(f"{arm}.state_estimated")
    builder.Connect(estimator.GetOutputPort("estimate"), sequencer.GetInputPort("marker_estimate"))
    builder.Connect(arm_state, sequencer.GetInputPort("arm_state"))
    command = sequencer.get_output_port(0)
    if planner_system is not None:
        builder.AddNamedSystem("planner", planner_system)
        builder.Connect(
            sequencer.GetOutputPort("planner_task"), planner_system.GetInputPort("task")
        )
        builder.Connect(planner_system.GetOutputPort("done"), sequencer.GetInputPort("move_done"))
        builder.Connect(arm_state, planner_system.GetInputPort("arm_state"))
        command = planner_system.GetOutputPort("position_commanded")
    builder.Connect(command, station.GetInputPort(f"{arm}.position_commanded"))
    return PanelOperationSystems(sequencer, estimator, degrade, kinematics, planner_system)
