"""Task `panel_operation`: the rover arm presses a panel switch guided by its camera
(Annusewicz-Mistal et al., "Autonomous Manipulator of a Mobile Robot Based on a Vision
System").

Diagram (AddPanelOperation, diagrams/tasks/panel_operation/builder.py): station (arm,
gripper camera rendered at `supersampling` x its resolution, panel) -> ImageDegradation
(pixel integration, lighting, blur, noise) -> MarkerPoseEstimator -> PanelOperation -> the
arm's position command (operation.motion "joint_trajectory"), or PanelOperation ->
AccelerationPlanner (Pająk's planner) -> the arm's position command (operation.motion "planner";
the planner's frames, limits and parameters under `planner`). The start is a random camera
pose in front of the panel (seeded: distance, tilt, aim point) solved by inverse
kinematics, so a marker is in view; or an explicit joint vector.

Metrics (frames as in systems/markers/marker_pose_estimator_math.py). The arm's poses
come from its measured joints through the nominal kinematics (what the controller
believes; the panel where it truly is); each has a `true_` twin from the true plant's
joints (and the camera's true mount), which differs only with station.errors:
  switch_pressed      1-based index of the switch whose cap travelled past its on-travel
                      (a list if several did, None if none): observed, not assumed;
  success             no failure and exactly the chosen switch pressed;
  base_position_error_mm  |camera position in P at the base point - its target|
                      (true_base_position_error_mm: the true camera's);
  base_camera_distance_mm the camera distance from the panel plane there;
  press_error_mm      {x, y, z}: |tip position in P while pressing - its target|
                      (true_press_error_mm: the true tip's);
  press_tip_W_mm, press_target_W_mm  that tip position and its target in the world
                      (the parked rover's) frame, as in the paper's Tables 5 and 6
                      (true_press_tip_W_mm: the true tip's);
  measurements        one record per image analysed (point, validity, ids, distance, the
                      estimated p_CP and its error estimate_error_mm against the believed
                      camera pose, true_estimate_error_mm against the true one);
  lost_measurements   how many images showed no marker (0 if they always did);
  marker_loss         what the sequencer did when markers were not visible ("abort" or
                      "continue" with the last valid estimate), None if they always were.
With `cover_markers_after_base` a cover slides in front of the markers once the base
measurement is taken (the paper's Table 6 case).
"""

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.overlays.panel_overlays import AddPanelOverlays
from guidedarm.diagrams.panel.panel_assets import COVER_CLOSED_M, WithGeneratedPanel
from guidedarm.diagrams.panel.panel_files import (
    LoadPanelSpec,
    RecordedCameraFiles,
    ResolvePanelFile,
    SupersampledCameraConfig,
)
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.common.planner_builder import MakeAccelerationPlanner
from guidedarm.diagrams.tasks.common.trajectory_csv import AddTrajectoryLogs
from guidedarm.diagrams.tasks.panel_operation.builder import AddPanelOperation
from guidedarm.diagrams.tasks.panel_operation.panel_start import (
    MakePanelCell,
    PanelCell,
    PanelStartPose,
    SampleStartPose,
)
from guidedarm.diagrams.tasks.panel_operation.report import (
    PANEL_OPERATION_METRICS,
    PanelOperationMetrics,
    PlotPanelOperation,
)
from guidedarm.diagrams.tasks.panel_operation.scenario import PanelOperationScenario
from guidedarm.diagrams.tasks.registry import RunFlags, TaskDefinition
from guidedarm.systems.cell_errors.camera_errors import ScaledCameraErrors
from guidedarm.systems.config_checks import CheckConfig, CheckInstance
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import SeededDegradation
from guidedarm.systems.markers.marker_pose_estimator_math import PanelSpec
from guidedarm.systems.panel.panel_operation_math import PlannerFrames
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_math import PlanningError


@dataclass(frozen=True)
class PreparedPanel:
    """What a panel operation checks before it runs and then builds on: the panel file,
    its markers and switches, the station scenario to simulate (SupersampledStation with
    the model generated from the panel file, WithGeneratedPanel), the cell's models that
    chose the start (PanelCell) and the start joints (rad, PanelStartPose)."""

    panel_file: Path
    panel: PanelSpec
    station: StationScenario
    cell: PanelCell
    q_start: np.ndarray


def PreparePanelOperation(scenario: PanelOperationScenario) -> PreparedPanel:
    """The panel, station and start of `scenario` after its checks (CheckConfig), refusing
    a panel_model that the station's directives do not add, an explicit start that touches
    the cell and a random_seed that gives no reachable start."""
    CheckInstance("scenario", scenario, PanelOperationScenario)
    CheckConfig(scenario)
    panel_file = ResolvePanelFile(scenario.panel_file)
    camera = scenario.station.cameras[scenario.camera]
    station = WithGeneratedPanel(
        SupersampledStation(scenario.station, scenario.camera, camera, scenario.supersampling),
        scenario.panel_model,
        panel_file,
    )
    panel = LoadPanelSpec(panel_file)
    cell = MakePanelCell(scenario, station)
    return PreparedPanel(panel_file, panel, station, cell, PanelStartPose(scenario, panel, cell))


class PanelOperationRun:
    """The diagram of one scenario (on `prepared`, default PreparePanelOperation(scenario));
    `Run(start)` simulates from a start joint vector, so several starts can share one
    build (the 10-run study)."""

    def __init__(
        self,
        scenario: PanelOperationScenario,
        context: RunContext,
        prepared: PreparedPanel | None = None,
    ) -> None:
        self.scenario = scenario
        self.context = context
        prepared = prepared or PreparePanelOperation(scenario)
        self.panel_file = prepared.panel_file
        self.panel = prepared.panel
        self.cell = prepared.cell
        self.collisions = prepared.cell.collisions
        self.X_WP = prepared.cell.X_WP
        self.q_start = prepared.q_start
        self._Build(prepared.station)

    def _Build(self, station_scenario: StationScenario) -> None:
        scenario = self.scenario
        k = scenario.supersampling
        builder = DiagramBuilder()
        self.station = builder.AddNamedSystem(
            "station", MakeStation(station_scenario, self.context.meshcat)
        )
        planner = None
        if scenario.operation.motion == "planner":
            planner = _MakePlanner(scenario)
        systems = AddPanelOperation(
            builder,
            self.station,
            station_scenario,
            self.panel,
            scenario.switch,
            arm=scenario.arm,
            camera=scenario.camera,
            tip_frame=scenario.tip_frame,
            operation=scenario.operation,
            degradation=dataclasses.replace(
                SeededDegradation(scenario.degradation, scenario.random_seed), supersampling=k
            ),
            planner=planner,
            intrinsics=scenario.EstimatorIntrinsics(),
            camera_mount=scenario.CameraMount(),
        )
        self.sequencer = systems.sequencer
        self.kinematics = systems.kinematics
        AddPanelOverlays(
            builder,
            self.context.meshcat,
            self.station,
            self.sequencer,
            self.kinematics,
            scenario.arm,
            systems.estimator.solver.intrinsics,
            self.panel.switches[scenario.switch - 1],
            scenario.panel_model,
        )
        command = (
            planner[0].GetOutputPort("position_commanded")
            if planner is not None
            else self.sequencer.get_output_port(0)
        )
        self.trajectory_logs = AddTrajectoryLogs(
            builder,
            command,
            self.station.GetOutputPort(f"{scenario.arm}.position_measured"),
            planner[0].GetOutputPort("planner_state") if planner is not None else None,
        )
        self.joint_log = builder.AddNamedSystem(
            "joint_log", VectorLogSink(self.kinematics.plant.num_positions(), 0.02)
        )
        builder.Connect(
            self.station.GetOutputPort(f"{scenario.arm}.position_measured"),
            self.joint_log.get_input_port(),
        )
        # The true plant's state (ground truth), for the true_ metrics.
        true_plant = self.station.GetSubsystemByName("plant")
        self.true_log = builder.AddNamedSystem(
            "true_state_log", VectorLogSink(true_plant.num_multibody_states(), TRUE_LOG_PERIOD)
        )
        builder.Connect(
            self.station.GetOutputPort("sim.plant_state"), self.true_log.get_input_port()
        )
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        ApplySimulatorConfig(scenario.station.simulator_config, self.simulator)
        self.context.pace(self.simulator, scenario.time_limit_s)
        self.plant: MultibodyPlant = self.station.GetSubsystemByName("plant")
        self.panel_instance = self.plant.GetModelInstanceByName(scenario.panel_model)
        self.arm_instance = self.plant.GetModelInstanceByName(scenario.arm)

    def SampleStart(self, seed: int) -> np.ndarray:
        """A random start from `seed` as the scenario's start settings draw it
        (SampleStartPose), for studies that run several starts on one build."""
        return SampleStartPose(self.scenario.start, self.panel, self.cell, seed)

    def Run(self, q_start: np.ndarray) -> dict[str, Any]:
        """Simulates the operation from q_start; returns the summary metrics."""
        scenario = self.scenario
        context = self.simulator.get_mutable_context()
        context.SetTime(0.0)
        self.diagram.SetDefaultContext(context)
        plant_context = self.plant.GetMyMutableContextFromRoot(context)
        self.plant.SetPositions(plant_context, self.arm_instance, q_start)
        self.joint_log.FindMutableLog(context).Clear()
        self.trajectory_logs.Clear(context)
        self.simulator.Initialize()
        self.context.start_recording()
        sequencer_context = self.sequencer.GetMyContextFromRoot(context)
        measured_base = self.sequencer.steps.index(
            next(s for s in self.sequencer.steps if s.kind == "measure" and s.label == "base")
        )
        covered = False
        planner_failure = None
        t = 0.0
        while t < scenario.time_limit_s:
            t = min(t + 0.1, scenario.time_limit_s)
            try:
                self.simulator.AdvanceTo(t)
            except PlanningError as e:
                step = self.sequencer.GetSequencerState(sequencer_context).step
                moves = [m.label for m in self.sequencer.steps[:step] if m.kind == "move"]
                planner_failure = f"planner, move to '{moves[-1]}': {e}"
                break
            state = self.sequencer.GetSequencerState(sequencer_context)
            if state.done:
                break
            if scenario.cover_markers_after_base and not covered and state.step > measured_base:
                cover = self.plant.GetJointByName("cover_slide", self.panel_instance)
                cover.set_translation(plant_context, COVER_CLOSED_M)
                covered = True
            self.context.progress(f"simulated {t:.1f} s, step {state.step}")
        self.context.write_replay()
        state = self.sequencer.GetSequencerState(sequencer_context)
        PlotPanelOperation(self, state, context)
        return PanelOperationMetrics(self, state, context, planner_failure)


# The period (s) of the true plant state's log: the true arm at the instants the
# sequencer records (it records them at rest, so the nearest sample is the pose).
TRUE_LOG_PERIOD = 0.01


def SupersampledStation(station: StationScenario, name: str, camera, k: int) -> StationScenario:
    """The station with camera `name` rendering k times its resolution, its pixel errors
    (station.errors.cameras, drawn) scaled with it."""
    cameras = dict(station.cameras)
    cameras[name] = SupersampledCameraConfig(camera, k)
    station = station.WithErrorsDrawn(None)
    errors = station.errors
    if name in errors.cameras:
        scaled = {**errors.cameras, name: ScaledCameraErrors(errors.cameras[name], k)}
        errors = dataclasses.replace(errors, cameras=scaled)
    return dataclasses.replace(station, cameras=cameras, errors=errors)


def _MakePlanner(scenario: PanelOperationScenario) -> tuple[AccelerationPlanner, PlannerFrames]:
    """The task-driven AccelerationPlanner (MakeAccelerationPlanner) and its frames."""
    config = scenario.planner
    planner = MakeAccelerationPlanner(
        scenario.station,
        scenario.arm,
        PlannerBaseFrame(scenario),
        scenario.tip_frame,
        None,
        config.parameters,
        config.max_joint_velocity,
        config.max_joint_acceleration,
    )
    kinematics = planner.planning.kinematics
    X_WB = kinematics.base_frame.CalcPoseInWorld(kinematics.plant.CreateDefaultContext())
    return planner, PlannerFrames(X_WB, RigidTransform())


def PlannerBaseFrame(scenario: PanelOperationScenario) -> str:
    """The planner's base frame: planner.base_frame, or the arm's `<arm>::base`."""
    return scenario.planner.base_frame or f"{scenario.arm}::base"


def CheckRun(scenario: PanelOperationScenario, flags: RunFlags) -> None:
    """Refuses --hardware (before the run): the task's station, success and metrics come
    from the simulation."""
    if flags.hardware:
        raise ConfigurationError(
            "panel_operation cannot run with --hardware: its station, success and metrics "
            "come from the simulated panel and rover (switch travel, true camera pose)"
        )


def RunPanelOperation(
    scenario: PanelOperationScenario, context: RunContext, prepared: PreparedPanel | None = None
) -> dict[str, Any]:
    """Builds the diagram on `prepared` (PreparePanelOperation) and simulates one operation
    from its start."""
    run = PanelOperationRun(scenario, context, prepared)
    return run.Run(run.q_start)


TASK = TaskDefinition(
    name="panel_operation",
    scenario_type=PanelOperationScenario,
    run=RunPanelOperation,
    description="rover arm presses a panel switch guided by markers (Annusewicz-Mistal et al.)",
    metrics=PANEL_OPERATION_METRICS,
    ground_truth_metrics=("switch_travel_mm.#", "press_target_W_mm.#"),
    check_run=CheckRun,
    resolve=RecordedCameraFiles,
    prepare=PreparePanelOperation,
)
