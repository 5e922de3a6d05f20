"""Task `waypoints`: an arm's TCP through waypoints with the acceleration-level planner.

The AccelerationPlanner (Pająk) streams commanded joint positions at 500 Hz to the
station's `<arm>.position_commanded`; the run reports the paper's Table 2 figures on the
commanded trajectory (what the planner produces) and the measured tracking error of the
simulated arm.
"""

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.overlays.waypoint_overlays import AddWaypointOverlays
from guidedarm.diagrams.plots import PlotJointSeries
from guidedarm.diagrams.run_context import AdvanceWithProgress, RunContext
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation, TruePose
from guidedarm.diagrams.tasks.planner_builder import MakeAccelerationPlanner, SymmetricLimit
from guidedarm.diagrams.tasks.planner_plots import PlotScaling, PlotTcpPath
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.diagrams.tasks.tracking import DelayedTrackingError, SampledCommands
from guidedarm.systems.config_checks import (
    CheckConfig,
    CheckFields,
    CheckInstance,
    NonNegative,
    Positive,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_config import (
    CheckModeFields,
)
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    ClosestApproach,
    PlannedTrajectory,
    PlannerConfig,
    PlannerState,
    PlanningError,
)

LIMIT_CHOICES = ("none", "velocity", "velocity,acceleration")


@dataclass
class WaypointsScenario:
    """arm: the arm of `station.arms` to move; base_frame, tool_frame: scoped frame names
    (e.g. `ur10e::base`, `ur10e::tool0`) of the base B and the TCP T.
    waypoints: rows [x, y, z, roll, pitch, yaw] of T in B (m, rad, Z-Y-X Euler angles); the
        last one is the final location. The start is the arm's initial position.
    limits: which of the paper's constraints are on: none, velocity, velocity,acceleration.
    max_joint_velocity, max_joint_acceleration: symmetric limits (rad/s, rad/s^2), one
        value for every joint or one per joint.
    planner: the planner's gains and settings. max_time: the run fails if the task has not
        ended by then (s); settle_time: simulated after the end (s).
    max_tracking_error: the run fails if the measured TCP is ever farther than this from
        the commanded one (m), at the delay (tracking.MAX_TRACKING_DELAY at most, reported
        as tracking_delay_s) that fits the measurement best: the planner's success alone
        says nothing of the arm.
    random_seed: the scenario's random seed (the draw of station.errors).
    """

    task: str = "waypoints"
    arm: str = ""
    base_frame: str = ""
    tool_frame: str = ""
    waypoints: list[list[float]] = field(default_factory=list)
    limits: str = "velocity,acceleration"
    max_joint_velocity: list[float] = Positive(factory=lambda: [1.0471975511965976])
    max_joint_acceleration: list[float] = Positive(factory=lambda: [1.3962634015954636])
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    max_time: float = Positive(20.0)
    settle_time: float = NonNegative(0.3)
    max_tracking_error: float = Positive(0.01)
    random_seed: int = 0
    station: StationScenario = field(default_factory=StationScenario)

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, `limits` one of LIMIT_CHOICES,
        at least one waypoint, and no key set that the run would not read
        (CheckReadKeys)."""
        CheckFields(self)
        if self.limits not in LIMIT_CHOICES:
            raise ConfigurationError(f"limits must be one of {LIMIT_CHOICES}, got '{self.limits}'")
        if not self.waypoints:
            raise ConfigurationError("waypoints: at least one waypoint is needed")
        CheckReadKeys(self)


@dataclass
class PlannerSetup:
    """The planner of a waypoints scenario (MakeAccelerationPlanner's LeafSystem), its law,
    controller plant, start q0 (rad), the waypoints' IK solutions (rad) and the symmetric
    limits (rad/s, rad/s^2; the scenario's even when a limit is switched off)."""

    planner: AccelerationPlanner
    plant: MultibodyPlant
    planning: AccelerationPlanning
    q0: np.ndarray
    joint_waypoints: np.ndarray
    velocity_limit: np.ndarray
    acceleration_limit: np.ndarray


def MakePlannerSetup(scenario: WaypointsScenario) -> PlannerSetup:
    """The scenario's planner through MakeAccelerationPlanner, which refuses bad input
    before any motion: unknown arm or frames, bad limits or gains, waypoints out of reach,
    and a near-singular start in the paper's mode; before those, the scenario's own checks
    (WaypointsScenario.Validate)."""
    CheckInstance("scenario", scenario, WaypointsScenario)
    CheckConfig(scenario)
    velocity = SymmetricLimit(scenario.max_joint_velocity, "max_joint_velocity")
    acceleration = SymmetricLimit(scenario.max_joint_acceleration, "max_joint_acceleration")
    planner = MakeAccelerationPlanner(
        scenario.station,
        scenario.arm,
        scenario.base_frame,
        scenario.tool_frame,
        scenario.waypoints,
        scenario.planner,
        velocity if scenario.limits != "none" else None,
        acceleration if scenario.limits == "velocity,acceleration" else None,
    )
    planning = planner.planning
    plant = planning.kinematics.plant
    q0 = plant.GetPositions(plant.CreateDefaultContext(), planning.kinematics.instance)
    return PlannerSetup(
        planner, plant, planning, q0, planning.joint_waypoints, velocity, acceleration
    )


def CheckReadKeys(scenario: WaypointsScenario) -> None:
    """Refuses a key set away from its default that the run would not read: a planner
    field of the other mode (CheckModeFields), or a joint limit that
    `limits` switches off."""
    CheckModeFields(scenario.planner)
    scenario_defaults = WaypointsScenario()
    for key, needs in (("max_joint_velocity", "velocity"), ("max_joint_acceleration", "accel")):
        changed = getattr(scenario, key) != getattr(scenario_defaults, key)
        if changed and needs not in scenario.limits:
            raise ConfigurationError(
                f"'{key}' has no effect with limits={scenario.limits}: remove it or switch "
                "the limit on (limits=velocity or velocity,acceleration)"
            )


def RunWaypoints(scenario: WaypointsScenario, context: RunContext) -> dict[str, Any]:
    """Simulates the planner driving the station's arm; returns the Table-2 metrics."""
    setup = MakePlannerSetup(scenario)
    arm = scenario.arm
    builder = DiagramBuilder()
    station = builder.AddNamedSystem(
        "station", MakeStation(scenario.station, context.meshcat, hardware=context.hardware)
    )
    planner = builder.AddNamedSystem("planner", setup.planner)
    builder.Connect(
        planner.GetOutputPort("position_commanded"),
        station.GetInputPort(f"{arm}.position_commanded"),
    )
    builder.Connect(station.GetOutputPort(f"{arm}.state_estimated"), planner.get_input_port())
    AddWaypointOverlays(
        builder,
        context.meshcat,
        setup.planning,
        planner.GetOutputPort("position_commanded"),
        setup.q0,
    )
    # Logged at every simulator step (both logs at the same instants), then reduced to one
    # sample per planner step: a periodic log would race the planner's update events.
    planner_log = builder.AddNamedSystem(
        "planner_log", VectorLogSink(planner.GetOutputPort("planner_state").size())
    )
    builder.Connect(planner.GetOutputPort("planner_state"), planner_log.get_input_port())
    measured_log = builder.AddNamedSystem("measured_log", VectorLogSink(6))
    builder.Connect(
        station.GetOutputPort(f"{arm}.position_measured"), measured_log.get_input_port()
    )
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.station.simulator_config, simulator)
    planner_context = planner.GetMyContextFromRoot(simulator.get_mutable_context())

    def monitor(root_context) -> EventStatus:
        done_time = planner.GetOutputPort("planner_state").Eval(planner_context)[-1]
        if 0 <= done_time <= root_context.get_time() - scenario.settle_time:
            return EventStatus.ReachedTermination(planner, "task ended")
        return EventStatus.DidNothing()

    simulator.set_monitor(monitor)
    failure = None
    context.start_recording()
    try:
        simulator.Initialize()
        t_end = AdvanceWithProgress(simulator, scenario.max_time, context)
    except PlanningError as e:
        failure = f"planner: {e}"
        t_end = simulator.get_context().get_time()
    context.write_replay()

    root = simulator.get_context()
    states = planner_log.FindLog(root).data()
    _, steps = np.unique(states[PlannerState.TIME_ROW], return_index=True)
    trajectory = PlannedTrajectory.FromStateVectors(states[:, steps])
    measured = measured_log.FindLog(root).data()[:, steps].T
    if failure is None and trajectory.done_time < 0:
        failure = f"the TCP did not reach the final waypoint within max_time {scenario.max_time} s"
    metrics = TrajectoryMetrics(setup, trajectory, measured)
    tracking = metrics.get("tcp_tracking_error_max_m", np.nan)
    if failure is None and not tracking <= scenario.max_tracking_error:
        failure = (
            f"the measured TCP strayed {tracking:.4g} m from the commanded one "
            f"(max_tracking_error {scenario.max_tracking_error} m)"
        )
    X_WT = TruePose(station, root, "world", scenario.tool_frame)
    if X_WT is not None:
        # The waypoints are in the nominal base frame: where the base is meant to be.
        kinematics = setup.planning.kinematics
        X_WB = kinematics.base_frame.CalcPoseInWorld(kinematics.plant.CreateDefaultContext())
        p_BT = X_WB.inverse() @ X_WT.translation()
        true_error = np.linalg.norm(p_BT - setup.planning.waypoints[-1, :3])
        metrics["true_final_error_m"] = float(true_error)
    context.headline.update(metrics)
    SavePlannerFigures(context, scenario, setup, trajectory, measured)
    return {"sim_time_s": round(t_end, 4), **metrics, "failure": failure}


# The numbers of RunWaypoints's summary (TaskDefinition.metrics): TrajectoryMetrics's and
# the simulated time; the tracking errors need the measured joints.
WAYPOINTS_METRICS = (
    "sim_time_s",
    "T_s",
    "qd_max",
    "qd_min",
    "qdd_max",
    "qdd_min",
    "final_error_m",
    "true_final_error_m",
    "c_min",
    "waypoint_distance_m.#",
    "qdd_step_max",
    "braking_steps",
    "tracking_error_max_rad",
    "tcp_tracking_error_max_m",
    "tracking_delay_s",
)


def TrajectoryMetrics(
    setup: PlannerSetup, trajectory: PlannedTrajectory, measured: np.ndarray | None = None
) -> dict[str, Any]:
    """The paper's Table 2 figures of a commanded trajectory, plus measured tracking."""
    kinematics = setup.planning.kinematics
    waypoints = setup.planning.waypoints
    tcp = np.array([kinematics.Position(q) for q in trajectory.q])
    done = trajectory.done_time >= 0
    k_end = int(np.searchsorted(trajectory.times, trajectory.done_time - 1e-9)) if done else -1
    final_error = float(np.linalg.norm(tcp[k_end, :3] - waypoints[-1, :3]))
    metrics: dict[str, Any] = {
        "T_s": round(trajectory.done_time, 4) if done else None,
        "qd_max": float(trajectory.qd.max()),
        "qd_min": float(trajectory.qd.min()),
        "qdd_max": float(trajectory.qdd.max()),
        "qdd_min": float(trajectory.qdd.min()),
        "final_error_m": final_error,
        "c_min": float(trajectory.c[1:].min()) if trajectory.c.size > 1 else 1.0,
        "waypoint_distance_m": ClosestApproach(tcp[:, :3], waypoints).round(5).tolist(),
        "qdd_step_max": float(np.abs(np.diff(trajectory.qdd, axis=0)).max(initial=0.0)),
        "braking_steps": int(trajectory.braking.sum()),
    }
    if measured is not None and measured.size:
        count = min(len(measured), len(trajectory.q))
        times = trajectory.times[:count]
        tcp_measured = np.array([kinematics.Position(q) for q in measured[:count]])
        delay, tcp_error = DelayedTrackingError(
            times, SampledCommands(times, tcp[:count, :3]), tcp_measured[:, :3]
        )
        joint_error = SampledCommands(times, trajectory.q[:count])(times - delay) - measured[:count]
        metrics["tracking_error_max_rad"] = float(np.abs(joint_error).max())
        metrics["tcp_tracking_error_max_m"] = tcp_error
        metrics["tracking_delay_s"] = delay
    return metrics


def PlotTcpPathsOfJoints(
    setup: PlannerSetup, joint_paths: dict[str, np.ndarray], radius: float
) -> Any:
    """PlotTcpPath of joint trajectories (samples x joints, rad), mapped to the TCP position
    by the planner's kinematics, with the task's waypoints, start and neighbourhoods (m)."""
    kinematics = setup.planning.kinematics
    paths = {
        name: np.array([kinematics.Position(q)[:3] for q in qs]) for name, qs in joint_paths.items()
    }
    return PlotTcpPath(paths, setup.planning.waypoints, radius, kinematics.Position(setup.q0))


def SavePlannerFigures(
    context: RunContext,
    scenario: WaypointsScenario,
    setup: PlannerSetup,
    trajectory: PlannedTrajectory,
    measured: np.ndarray,
) -> None:
    """TCP path, q, qd, qdd (limits dashed) and c(t), like the paper's figures 2-14."""
    joint_paths = {"commanded": trajectory.q}
    if measured.size:
        joint_paths["measured"] = measured
    context.save_figure(
        PlotTcpPathsOfJoints(setup, joint_paths, scenario.planner.neighbourhood_radius),
        "tcp_path",
    )
    times = trajectory.times
    series = {"commanded": trajectory.q.T}
    if measured.size:
        count = min(len(measured), len(times))
        series = {"commanded": trajectory.q[:count].T, "measured": measured[:count].T}
        times = times[:count]
    context.save_figure(PlotJointSeries(times, series, "q (rad)"), "joint_positions")
    velocity, acceleration = setup.velocity_limit, setup.acceleration_limit
    context.save_figure(
        PlotJointSeries(
            trajectory.times,
            {"commanded": trajectory.qd.T},
            "qd (rad/s)",
            (-velocity, velocity) if setup.planning.penalty else None,
        ),
        "joint_velocities",
    )
    context.save_figure(
        PlotJointSeries(
            trajectory.times,
            {"commanded": trajectory.qdd.T},
            "qdd (rad/s^2)",
            (-acceleration, acceleration) if setup.planning.scaling else None,
        ),
        "joint_accelerations",
    )
    context.save_figure(PlotScaling(trajectory.times, trajectory.c), "scaling_coefficient")


TASK = TaskDefinition(
    name="waypoints",
    scenario_type=WaypointsScenario,
    run=RunWaypoints,
    description="TCP through waypoints with the acceleration-level planner (Pająk)",
    metrics=WAYPOINTS_METRICS,
)
