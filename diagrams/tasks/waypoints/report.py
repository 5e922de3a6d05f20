"""The summary metrics (the paper's Table 2 figures, the measured tracking) and the
figures of a `waypoints` run."""

from typing import Any

import numpy as np

from guidedarm.diagrams.plots import PlotJointSeries
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.common.tracking import DelayedTrackingError, SampledCommands
from guidedarm.diagrams.tasks.common.trajectory_csv import JOINT_MOTION_METRICS, JointMotionMetrics
from guidedarm.diagrams.tasks.waypoints.plots import PlotScaling, PlotTcpPath
from guidedarm.diagrams.tasks.waypoints.scenario import WaypointsScenario
from guidedarm.diagrams.tasks.waypoints.setup import PlannerSetup
from guidedarm.systems.planning.acceleration_planner_math import ClosestApproach, PlannedTrajectory

# The numbers of RunWaypoints's summary (TaskDefinition.metrics): TrajectoryMetrics's and
# the simulated time; the tracking errors need the measured joints.
WAYPOINTS_METRICS = {
    "sim_time_s": ("s", "simulated time of the run"),
    "T_s": (
        "s",
        "the task's time: the first instant the TCP is within epsilon of the last waypoint",
    ),
    "qd_max": ("rad/s", "largest commanded joint velocity, any joint"),
    "qd_min": ("rad/s", "smallest (most negative) commanded joint velocity"),
    "qdd_max": ("rad/s^2", "largest commanded joint acceleration"),
    "qdd_min": ("rad/s^2", "smallest commanded joint acceleration"),
    "final_error_m": ("m", "TCP distance from the last waypoint at T_s (commanded trajectory)"),
    "true_final_error_m": (
        "m",
        "the true TCP's distance from the last waypoint at the end (the true cell's arm)",
    ),
    "true_move_error_m": (
        "m",
        "the true TCP's travel from its start to its end along the commanded move, minus "
        "the move's length (what a dial indicator along the move reads: seed 003 Table 1)",
    ),
    "c_min": ("ratio", "smallest acceleration scaling c(t) after the start (1: never scaled)"),
    "waypoint_distance_m.#": ("m", "closest approach of the commanded TCP to each waypoint"),
    "qdd_step_max": ("rad/s^2", "largest change of a commanded acceleration in one step"),
    "braking_steps": ("count", "steps on the robust mode's braking fallback"),
    "handover_time_s": (
        "s",
        "when the robust mode handed over to joint space (-1: never; docs/planner.md)",
    ),
    **JOINT_MOTION_METRICS,
    "tracking_error_max_rad": (
        "rad",
        "largest joint distance of the measured arm from the commands, at tracking_delay_s",
    ),
    "tcp_tracking_error_max_m": (
        "m",
        "largest TCP distance of the measured from the commanded path",
    ),
    "tracking_delay_s": (
        "s",
        "the delay of the measured arm behind the commands that fits it best (0 in simulation)",
    ),
}


def MoveError(travel: np.ndarray, commanded: np.ndarray) -> float:
    """|travel along the commanded move - the move's length| (m): the error a dial indicator
    aligned with the commanded displacement `commanded` (m, 3-vector) reads for the true
    displacement `travel` (m)."""
    length = float(np.linalg.norm(commanded))
    if length == 0.0:
        return float(np.linalg.norm(travel))
    return abs(float(np.dot(travel, commanded)) / length - length)


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
        **JointMotionMetrics(
            trajectory.q,
            trajectory.qdd,
            kinematics.PositionLimits(),
            setup.acceleration_limit,
            setup.planning.parameters.time_step,
        ),
        # -1: the law kept to the Cartesian line (no hand-over to joint space)
        "handover_time_s": round(trajectory.handover_time, 4),
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
