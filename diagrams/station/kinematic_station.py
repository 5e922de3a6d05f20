"""MakeKinematicStation: the station without dynamics, the arm posed where it is commanded.

The plant of the scenario's models (hose included) on a SceneGraph, its one arm's joints
set from the command, and its ToF tools reading that SceneGraph (station_wiring, as the
simulated station's). It stands in for the simulated station where the servo's dynamics
do not matter (path following's `kinematic` executor, contact counts, replays).
"""

from __future__ import annotations

from pydrake.geometry import Meshcat, SceneGraph
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import PassThrough
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import (
    ArmCalibrationOffset,
    GetArmInstance,
    MakeMultibodyPlant,
)
from guidedarm.diagrams.station.station_wiring import (
    AddMeshcatVisualization,
    AddOffset,
    AddToFTools,
)
from guidedarm.systems.config_checks import CheckConfig, CheckInstance
from guidedarm.systems.errors import ConfigurationError


def MakeKinematicStation(scenario: StationScenario, meshcat: Meshcat | None = None) -> Diagram:
    """A station without dynamics: the plant of the scenario's models (hose included) on a
    SceneGraph, posed where its one arm is commanded, and its ToF tools reading that
    SceneGraph; drawn in `meshcat` as MakeStation draws its plant, if given. Ports as
    MakeStation's: input `<arm>.position_commanded` (n, rad); outputs
    `<arm>.position_measured` (n, rad; the command itself), `<tof>.ranges`, `<tof>.valid`,
    `<tof>.measured_at`, `<tof>.detections`, `<tof>.detection_errors`, and
    `sim.query_object`."""
    CheckInstance("scenario", scenario, StationScenario)
    CheckConfig(scenario, "scenario")
    if len(scenario.arms) != 1:
        raise ConfigurationError("the kinematic station takes exactly one arm")
    (arm,) = scenario.arms
    builder = DiagramBuilder()
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = MakeMultibodyPlant(scenario, with_hose=True, scene_graph=scene_graph)
    n = plant.num_positions(GetArmInstance(plant, arm))
    if plant.num_positions() != n:
        raise ConfigurationError(
            f"the kinematic station needs arms.{arm}'s joints to be the station's only joints "
            f"({plant.num_positions()} positions, the arm has {n})"
        )
    command = builder.AddNamedSystem(f"{arm}.command", PassThrough(n))
    to_pose = builder.AddNamedSystem("plant_pose", MultibodyPositionToGeometryPose(plant))
    pose = command.get_output_port()
    calibration = ArmCalibrationOffset(scenario, arm, n)
    if calibration is not None:
        # An exact arm read through a calibration file: the joints stand at the command
        # minus the file's offsets; the reading plus them is the command again.
        to_arm = AddOffset(builder, f"{arm}.command_calibration", -calibration)
        builder.Connect(pose, to_arm.get_input_port())
        pose = to_arm.get_output_port()
    builder.Connect(pose, to_pose.get_input_port())
    builder.Connect(
        to_pose.get_output_port(), scene_graph.get_source_pose_port(plant.get_source_id())
    )
    builder.ExportInput(command.get_input_port(), f"{arm}.position_commanded")
    builder.ExportOutput(command.get_output_port(), f"{arm}.position_measured")
    AddToFTools(builder, scenario, plant, scene_graph)
    AddMeshcatVisualization(builder, scenario, meshcat, plant, scene_graph)
    builder.ExportOutput(scene_graph.get_query_output_port(), "sim.query_object")
    diagram = builder.Build()
    diagram.set_name("kinematic_station")
    return diagram
