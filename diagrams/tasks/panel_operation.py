"""Task `panel_operation`: the rover arm presses a panel switch guided by its camera (seed 003).

Diagram: station (arm, gripper camera rendered at `supersampling` x its resolution, panel)
-> ImageDegradation (pixel integration, lighting, blur, noise) -> MarkerPoseEstimator ->
PanelOperation -> the arm's position command (operation.motion "joint_trajectory"), or
PanelOperation -> AccelerationPlanner (seed 001) -> the arm's position command
(operation.motion "planner"; the planner's frames, limits and parameters under `planner`).
The start is a random camera pose in front of
the panel (seeded: distance, tilt, aim point) solved by inverse kinematics, so a marker is
in view; or an explicit joint vector.

Metrics (ground truth from the simulation; frames as in
systems/markers/marker_pose_estimator_math.py):
  switch_pressed      1-based index of the switch whose cap travelled past its on-travel
                      (a list if several did, None if none): observed, not assumed;
  success             no failure and exactly the chosen switch pressed;
  base_position_error_mm  |true camera position in P at the base point - its target|;
  base_camera_distance_mm the true camera distance from the panel plane there;
  press_error_mm      {x, y, z}: |true tip position in P while pressing - its target|;
  press_tip_W_mm, press_target_W_mm  that tip position and its target in the world
                      (the parked rover's) frame, as in the seed's Tables 5 and 6;
  measurements        one record per image analysed (point, validity, ids, distance, the
                      estimated p_CP and its true error estimate_error_mm);
  marker_loss         what the sequencer did when markers were not visible ("abort" or
                      "continue" with the last valid estimate), None if they always were.
With `cover_markers_after_base` a cover slides in front of the markers once the base
measurement is taken (the seed's Table 6 case).
"""

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.plots import PlotJointSeries
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.model_paths import MODELS_DIR, MakeParser
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.panel_assets import COVER_CLOSED_M
from guidedarm.diagrams.tasks.panel_camera_rig import LookAt
from guidedarm.diagrams.tasks.panel_files import (
    IntrinsicsFromCameraConfig,
    LoadPanelSpec,
    SupersampledCameraConfig,
)
from guidedarm.diagrams.tasks.planner_builder import MakeAccelerationPlanner
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig, ImageDegradation
from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver
from guidedarm.systems.markers.panel_operation import (
    CameraArmKinematics,
    PanelOperation,
    PanelOperationConfig,
    PlannerFrames,
)
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig, PlanningError


@dataclass
class StartConfig:
    """position: explicit start joints (rad); empty draws a camera pose with `seed`:
    distance to the aim point in distance_m [min, max] (m), tilt from the panel normal up to
    max_tilt_deg, aim point within aim_offset_m of the markers' middle."""

    position: list[float] = field(default_factory=list)
    seed: int = 0
    distance_m: list[float] = field(default_factory=lambda: [0.30, 0.40])
    max_tilt_deg: float = 30.0
    aim_offset_m: float = 0.02


@dataclass
class PanelPlannerConfig:
    """The acceleration-level planner of operation.motion "planner" (MakeAccelerationPlanner
    on the station's own models of the arm and gripper). base_frame: its base B (scoped
    frame name); its TCP is the scenario's tip frame. max_joint_velocity,
    max_joint_acceleration: symmetric limits, one value or one per joint (rad/s, rad/s^2).
    parameters: the law's gains and settings (the robust mode by default: facing the panel
    the tip is at Z-Y-X pitch -90 deg, the Euler singularity of the seed's law)."""

    base_frame: str = ""
    max_joint_velocity: list[float] = field(default_factory=lambda: [0.5])
    max_joint_acceleration: list[float] = field(default_factory=lambda: [1.5])
    parameters: PlannerConfig = field(default_factory=PlannerConfig)


@dataclass
class PanelOperationScenario:
    """switch: 1-based index into the panel file's switches. camera: the key of
    station.cameras on the arm (1920 x 1080 C920 by default), rendered at `supersampling`
    times its resolution. panel_file: PANEL.yaml relative to models/; panel_model: its
    model instance in the directives. arm_directives: the arm as its controller knows it
    (kinematics for IK), without the panel. time_limit_s: simulated time allowed."""

    task: str = "panel_operation"
    arm: str = "rover_arm"
    switch: int = 2
    camera: str = "camera"
    tip_frame: str = "rover_gripper::gripper_tip"
    arm_directives: str = "package://guidedarm/directives/rover_arm.dmd.yaml"
    panel_file: str = "panel/panel.yaml"
    panel_model: str = "panel"
    supersampling: int = 3
    degradation: DegradationConfig = field(default_factory=DegradationConfig)
    start: StartConfig = field(default_factory=StartConfig)
    cover_markers_after_base: bool = False
    operation: PanelOperationConfig = field(default_factory=PanelOperationConfig)
    planner: PanelPlannerConfig = field(default_factory=PanelPlannerConfig)
    time_limit_s: float = 40.0
    station: StationScenario = field(default_factory=StationScenario)


class PanelOperationRun:
    """The diagram of one scenario; `Run(start)` simulates from a start joint vector, so
    several starts can share one build (the 10-run study)."""

    def __init__(self, scenario: PanelOperationScenario, context: RunContext) -> None:
        self.scenario = scenario
        self.context = context
        self.panel = LoadPanelSpec(MODELS_DIR / scenario.panel_file)
        if not 1 <= scenario.switch <= len(self.panel.switches):
            raise ConfigurationError(
                f"switch must be 1 .. {len(self.panel.switches)}, got {scenario.switch}"
            )
        if scenario.camera not in scenario.station.cameras:
            raise ConfigurationError(f"camera '{scenario.camera}' is not in station.cameras")
        if scenario.arm not in scenario.station.arms:
            raise ConfigurationError(f"arm '{scenario.arm}' is not in station.arms")
        if scenario.degradation.supersampling != 1 or scenario.supersampling < 1:
            raise ConfigurationError(
                "set the camera's supersampling (>= 1) with the top-level key 'supersampling'"
            )
        self.kinematics = _MakeArmKinematics(scenario)
        self._Build()

    def _Build(self) -> None:
        scenario = self.scenario
        k = scenario.supersampling
        camera = scenario.station.cameras[scenario.camera]
        station_scenario = _replace_camera(scenario.station, scenario.camera, camera, k)
        builder = DiagramBuilder()
        self.station = builder.AddNamedSystem(
            "station", MakeStation(station_scenario, self.context.meshcat)
        )
        rendered = station_scenario.cameras[scenario.camera]
        params = DegradationConfig(**{**scenario.degradation.__dict__, "supersampling": k})
        degradation = builder.AddNamedSystem("image_degradation", ImageDegradation(params))
        solver = MarkerPoseSolver(IntrinsicsFromCameraConfig(rendered, k), self.panel)
        estimator = builder.AddNamedSystem("marker_pose_estimator", MarkerPoseEstimator(solver))
        switch = self.panel.switches[scenario.switch - 1]
        planner, frames = None, None
        if scenario.operation.motion == "planner":
            planner, frames = _MakePlanner(scenario)
        self.sequencer = builder.AddNamedSystem(
            "panel_operation",
            PanelOperation(self.kinematics, self.panel, switch, scenario.operation, frames),
        )
        builder.Connect(
            self.station.GetOutputPort(f"{scenario.camera}.rgb_image"),
            degradation.get_input_port(),
        )
        builder.Connect(degradation.get_output_port(), estimator.get_input_port())
        builder.Connect(
            estimator.GetOutputPort("estimate"), self.sequencer.GetInputPort("marker_estimate")
        )
        builder.Connect(
            self.station.GetOutputPort(f"{scenario.arm}.state_estimated"),
            self.sequencer.GetInputPort("arm_state"),
        )
        command = self.sequencer.get_output_port()
        if planner is not None:
            builder.AddNamedSystem("planner", planner)
            builder.Connect(
                self.sequencer.GetOutputPort("planner_task"), planner.GetInputPort("task")
            )
            builder.Connect(planner.GetOutputPort("done"), self.sequencer.GetInputPort("move_done"))
            builder.Connect(
                self.station.GetOutputPort(f"{scenario.arm}.state_estimated"),
                planner.GetInputPort("arm_state"),
            )
            command = planner.GetOutputPort("position_commanded")
        builder.Connect(command, self.station.GetInputPort(f"{scenario.arm}.position_commanded"))
        self.joint_log = builder.AddNamedSystem(
            "joint_log", VectorLogSink(self.kinematics.plant.num_positions(), 0.02)
        )
        builder.Connect(
            self.station.GetOutputPort(f"{scenario.arm}.position_measured"),
            self.joint_log.get_input_port(),
        )
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        ApplySimulatorConfig(scenario.station.simulator_config, self.simulator)
        self.plant: MultibodyPlant = self.station.GetSubsystemByName("plant")
        self.panel_instance = self.plant.GetModelInstanceByName(scenario.panel_model)
        self.arm_instance = self.plant.GetModelInstanceByName(scenario.arm)
        plant_context = self.plant.CreateDefaultContext()
        self.X_WP = self.plant.GetFrameByName("plate", self.panel_instance).CalcPoseInWorld(
            plant_context
        )

    def SampleStart(self, seed: int) -> np.ndarray:
        """A start joint vector whose camera sees the panel from a random pose (see
        StartConfig), by inverse kinematics from the arm's default position."""
        start = self.scenario.start
        rng = np.random.default_rng(seed)
        centres = [m.X_PM.GetDeterministicValue().translation() for m in self.panel.markers]
        middle = np.mean(centres, axis=0)
        q_default = self.kinematics.plant.GetPositions(self.kinematics.plant.CreateDefaultContext())
        for _ in range(50):
            aim = middle + np.append(rng.uniform(-1, 1, 2) * start.aim_offset_m, 0.0)
            tilt = np.radians(rng.uniform(0.0, start.max_tilt_deg))
            azimuth = rng.uniform(0.0, 2 * np.pi)
            direction = [
                np.sin(tilt) * np.cos(azimuth),
                np.sin(tilt) * np.sin(azimuth),
                np.cos(tilt),
            ]
            p_PC = aim + rng.uniform(*start.distance_m) * np.asarray(direction)
            X_WT = self.X_WP @ LookAt(p_PC, aim) @ self.kinematics.X_CT
            q = self.kinematics.SolveTip(X_WT, q_default)
            if q is not None:
                return q
        raise ConfigurationError(f"no reachable start pose found for seed {seed}")

    def Run(self, q_start: np.ndarray) -> dict[str, Any]:
        """Simulates the operation from q_start; returns the summary metrics."""
        scenario = self.scenario
        context = self.simulator.get_mutable_context()
        context.SetTime(0.0)
        self.diagram.SetDefaultContext(context)
        plant_context = self.plant.GetMyMutableContextFromRoot(context)
        self.plant.SetPositions(plant_context, self.arm_instance, q_start)
        self.joint_log.FindMutableLog(context).Clear()
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
        self._Plot(state, context)
        return self._Metrics(state, context, planner_failure)

    def _Plot(self, state, context) -> None:
        """joints.png (measured joints) and tip_distance.png (tip to panel plane, with the
        instants at which images were analysed)."""
        import matplotlib.pyplot as plt  # after guidedarm.diagrams.plots chose Agg

        log = self.joint_log.FindLog(context)
        times, q = log.sample_times(), log.data()
        if times.size < 2:
            return
        self.context.save_figure(PlotJointSeries(times, {"measured": q}, "q (rad)"), "joints")
        X_PW = self.X_WP.inverse()
        depth = [
            1e3 * (X_PW @ self.kinematics.X_WT(q[:, i])).translation()[2] for i in range(times.size)
        ]
        figure, axes = plt.subplots(figsize=(7, 3))
        axes.plot(times, depth, label="tip in front of the panel plane")
        for record in state.measurements:
            axes.axvline(record["t_s"], color="g" if record["valid"] else "r", linestyle="--")
        axes.set_xlabel("t (s)")
        axes.set_ylabel("z of the tip in P (mm)")
        axes.set_title("panel operation: dashed = image analysed (green valid, red lost)")
        axes.grid(True, alpha=0.3)
        self.context.save_figure(figure, "tip_distance")

    def _Metrics(self, state, context, planner_failure: str | None = None) -> dict[str, Any]:
        scenario = self.scenario
        plant_context = self.plant.GetMyContextFromRoot(context)
        travels = [
            -self.plant.GetJointByName(s.name, self.panel_instance).get_translation(plant_context)
            for s in self.panel.switches
        ]
        pressed = [
            i + 1
            for i, (s, travel) in enumerate(zip(self.panel.switches, travels, strict=True))
            if travel >= s.on_travel_m
        ]
        failure = planner_failure or state.failure
        if failure is None and not state.done:
            failure = f"the sequence did not finish within {scenario.time_limit_s} s"
        if failure is None and pressed != [scenario.switch]:
            failure = f"pressed switches {pressed}, expected [{scenario.switch}]"
        targets = self.sequencer.targets
        X_PW = self.X_WP.inverse()
        base_error = base_distance = None
        if "measure_base" in state.q_at:
            X_PC = X_PW @ self.kinematics.X_WC(np.array(state.q_at["measure_base"]))
            X_PC_target = targets.base() @ self.kinematics.X_CT.inverse()
            base_error = _mm(np.linalg.norm(X_PC.translation() - X_PC_target.translation()))
            base_distance = _mm(X_PC.translation()[2])
        press_error = press_tip = None
        target_W = self.X_WP @ targets.at_switch(-scenario.operation.press_depth_m)
        if "press" in state.q_at:
            X_WT = self.kinematics.X_WT(np.array(state.q_at["press"]))
            p_PT = (X_PW @ X_WT).translation()
            target = targets.at_switch(-scenario.operation.press_depth_m).translation()
            press_error = dict(zip("xyz", (_mm(abs(e)) for e in p_PT - target), strict=True))
            press_tip = [_mm(v) for v in X_WT.translation()]
        for record in state.measurements:
            if "p_CP_mm" in record:
                X_WC = self.kinematics.X_WC(np.array(state.q_at[f"measure_{record['point']}"]))
                p_CP = (X_WC.inverse() @ self.X_WP).translation()
                record["estimate_error_mm"] = _mm(
                    np.linalg.norm(1e-3 * np.array(record["p_CP_mm"]) - p_CP)
                )
        lost = [m for m in state.measurements if not m["valid"]]
        return {
            "success": failure is None,
            "switch": scenario.switch,
            "switch_pressed": pressed[0] if len(pressed) == 1 else (pressed or None),
            "switch_travel_mm": [_mm(t) for t in travels],
            "base_position_error_mm": base_error,
            "base_camera_distance_mm": base_distance,
            "press_error_mm": press_error,
            "press_tip_W_mm": press_tip,
            "press_target_W_mm": [_mm(v) for v in target_W.translation()],
            "measurements": state.measurements,
            "marker_loss": scenario.operation.on_marker_loss if lost else None,
            "failure": failure,
            "sim_time_s": round(context.get_time(), 3),
        }


def _mm(value: float) -> float:
    return round(1000.0 * float(value), 3)


def _replace_camera(station: StationScenario, name: str, camera, k: int) -> StationScenario:
    cameras = dict(station.cameras)
    cameras[name] = SupersampledCameraConfig(camera, k)
    return StationScenario(**{**station.__dict__, "cameras": cameras})


def _LoadArmPlant(scenario: PanelOperationScenario) -> MultibodyPlant:
    """The arm as its controller knows it (not finalized)."""
    plant = MultibodyPlant(0.0)
    try:
        directives = LoadModelDirectives(
            MakeParser(plant).package_map().ResolveUrl(scenario.arm_directives)
        )
        ProcessModelDirectives(directives, MakeParser(plant))
    except Exception as e:
        raise ConfigurationError(f"arm_directives: {str(e).splitlines()[0]}") from None
    return plant


def _MakePlanner(scenario: PanelOperationScenario) -> tuple[AccelerationPlanner, PlannerFrames]:
    """The task-driven AccelerationPlanner (MakeAccelerationPlanner) and its frames."""
    config = scenario.planner
    planner = MakeAccelerationPlanner(
        scenario.station,
        scenario.arm,
        config.base_frame,
        scenario.tip_frame,
        None,
        config.parameters,
        config.max_joint_velocity,
        config.max_joint_acceleration,
    )
    kinematics = planner.planning.kinematics
    X_WB = kinematics.base_frame.CalcPoseInWorld(kinematics.plant.CreateDefaultContext())
    return planner, PlannerFrames(X_WB, RigidTransform())


def _MakeArmKinematics(scenario: PanelOperationScenario) -> CameraArmKinematics:
    plant = _LoadArmPlant(scenario)
    plant.Finalize()
    camera = scenario.station.cameras[scenario.camera].X_PB.base_frame or ""
    frames = []
    for scoped in (camera, scenario.tip_frame):
        instance, _, name = scoped.rpartition("::")
        if not instance or not plant.HasModelInstanceNamed(instance):
            raise ConfigurationError(f"frame '{scoped}' is not in {scenario.arm_directives}")
        frames.append(plant.GetFrameByName(name, plant.GetModelInstanceByName(instance)))
    return CameraArmKinematics(plant, *frames)


def RunPanelOperation(scenario: PanelOperationScenario, context: RunContext) -> dict[str, Any]:
    """Builds the diagram, picks the start and simulates one operation."""
    run = PanelOperationRun(scenario, context)
    start = scenario.start
    q_start = np.asarray(start.position, float) if start.position else run.SampleStart(start.seed)
    return run.Run(q_start)


TASK = TaskDefinition(
    name="panel_operation",
    scenario_type=PanelOperationScenario,
    run=RunPanelOperation,
    description="rover arm presses a panel switch guided by fiducial markers (seed 003)",
)
