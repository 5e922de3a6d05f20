"""Task `waypoints`: an arm's TCP through waypoints with the acceleration-level planner.

The AccelerationPlanner (Pająk) streams commanded joint positions at 500 Hz to the
station's `<arm>.position_commanded`; the run reports the paper's Table 2 figures on the
commanded trajectory (what the planner produces) and the measured tracking error of the
simulated arm.
"""

from typing import Any

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.overlays.waypoint_overlays import AddWaypointOverlays
from guidedarm.diagrams.run_context import AdvanceWithProgress, RunContext
from guidedarm.diagrams.station.station import MakeStation, TruePose
from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions
from guidedarm.diagrams.tasks.common.trajectory_csv import WriteTrajectoryCsv
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.diagrams.tasks.waypoints.report import (
    WAYPOINTS_METRICS,
    MoveError,
    SavePlannerFigures,
    TrajectoryMetrics,
)
from guidedarm.diagrams.tasks.waypoints.scenario import WaypointsScenario
from guidedarm.diagrams.tasks.waypoints.setup import PlannerSetup, PrepareWaypoints
from guidedarm.systems.planning.acceleration_planner_math import (
    PlannedTrajectory,
    PlannerState,
    PlanningError,
)


def RunWaypoints(
    scenario: WaypointsScenario,
    context: RunContext,
    prepared: tuple[PlannerSetup, CellCollisions] | None = None,
) -> dict[str, Any]:
    """Simulates the planner driving the station's arm (`prepared`, default
    PrepareWaypoints(scenario)); returns the Table-2 metrics."""
    setup, collisions = prepared or PrepareWaypoints(scenario)
    arm = scenario.arm
    builder = DiagramBuilder()
    station = builder.AddNamedSystem(
        "station", MakeStation(scenario.station, context.meshcat, context.station_kind)
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
        state = planner.GetOutputPort("planner_state").Eval(planner_context)
        done_time = state[PlannerState.DONE_ROW]
        if 0 <= done_time <= root_context.get_time() - scenario.settle_time:
            return EventStatus.ReachedTermination(planner, "task ended")
        return EventStatus.DidNothing()

    simulator.set_monitor(monitor)
    failure = None
    context.start_recording()
    p_start = _TrueTcp(station, simulator.get_context(), scenario, setup)
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
    metrics["cell_contacts"] = collisions.CountContacts(measured[::10])
    p_end = _TrueTcp(station, root, scenario, setup)
    if p_end is not None:
        target = setup.planning.waypoints[-1, :3]
        metrics["true_final_error_m"] = float(np.linalg.norm(p_end - target))
        # The planner starts where the encoders say the arm is.
        p_believed = setup.planning.kinematics.Position(measured[0])[:3]
        metrics["true_move_error_m"] = MoveError(p_end - p_start, target - p_believed)
    context.headline.update(metrics)
    SavePlannerFigures(context, scenario, setup, trajectory, measured)
    WriteTrajectoryCsv(
        context, trajectory.times, trajectory.q, trajectory.qd, trajectory.qdd, measured
    )
    return {"sim_time_s": round(t_end, 4), **metrics, "failure": failure}


def _TrueTcp(
    station, root_context, scenario: WaypointsScenario, setup: PlannerSetup
) -> np.ndarray | None:
    """The true TCP's position (m) in the nominal base frame, where the waypoints are (the
    base where it is meant to be); None on hardware."""
    X_WT = TruePose(station, root_context, "world", scenario.tool_frame)
    if X_WT is None:
        return None
    kinematics = setup.planning.kinematics
    X_WB = kinematics.base_frame.CalcPoseInWorld(kinematics.plant.CreateDefaultContext())
    return X_WB.inverse() @ X_WT.translation()


TASK = TaskDefinition(
    name="waypoints",
    scenario_type=WaypointsScenario,
    run=RunWaypoints,
    description="TCP through waypoints with the acceleration-level planner (Pająk)",
    metrics=WAYPOINTS_METRICS,
    prepare=PrepareWaypoints,
)
