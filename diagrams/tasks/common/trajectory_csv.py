"""trajectory.csv of a run, and the joint-motion figures every arm task reports.

Every run folder of the waypoints, joint_tour and panel_operation tasks holds its time
series as `trajectory.csv`, one row per control period: `t` (s), then `q_cmd_1..n` (rad),
`qd_cmd_1..n` (rad/s), `qdd_cmd_1..n` (rad/s^2) and `q_meas_1..n` (rad), so users can
analyse a run with their own tools (as path following's steps.csv).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.framework import Context, DiagramBuilder, OutputPort
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.run_context import RunContext
from guidedarm.systems.planning.acceleration_planner_watch import ReversalRates

TRAJECTORY_CSV = "trajectory"


def TrajectoryHeader(n: int) -> list[str]:
    """The columns of trajectory.csv for n joints."""
    names = ["t"]
    for prefix in ("q_cmd", "qd_cmd", "qdd_cmd", "q_meas"):
        names += [f"{prefix}_{i + 1}" for i in range(n)]
    return names


def WriteTrajectoryCsv(
    context: RunContext,
    times: np.ndarray,
    q_cmd: np.ndarray,
    qd_cmd: np.ndarray,
    qdd_cmd: np.ndarray,
    q_meas: np.ndarray,
) -> Path:
    """Writes trajectory.csv (rows: samples; the arrays samples x joints, rad, rad/s,
    rad/s^2; times s) into the run folder."""
    count = min(len(times), len(q_cmd), len(q_meas))
    table = np.column_stack(
        [times[:count], q_cmd[:count], qd_cmd[:count], qdd_cmd[:count], q_meas[:count]]
    )
    return context.write_csv(
        TRAJECTORY_CSV, TrajectoryHeader(q_cmd.shape[1]), np.round(table, 9).tolist()
    )


def FiniteDifferences(times: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """qd, qdd (rad/s, rad/s^2) of sampled positions q (samples x joints) by np.gradient."""
    if len(times) < 3:
        return np.zeros_like(q), np.zeros_like(q)
    qd = np.gradient(q, times, axis=0)
    return qd, np.gradient(qd, times, axis=0)


# The docs of JointMotionMetrics's and CountContacts's figures (TaskDefinition.metrics).
JOINT_MOTION_METRICS = {
    "joint_limit_distance_min_rad": (
        "rad",
        "smallest distance of a commanded joint from its position limit (negative: past it)",
    ),
    "oscillation_rate_max": (
        "1/s",
        "largest rate of sign reversals of a commanded joint acceleration beyond half its "
        "limit (the oscillation measure, docs/planner.md)",
    ),
    "cell_contacts": (
        "count",
        "contact episodes of the measured arm with its cell or itself (sampled every 20 ms)",
    ),
}


def JointMotionMetrics(
    q: np.ndarray,
    qdd: np.ndarray,
    position_limits: tuple[np.ndarray, np.ndarray],
    acceleration_limit: np.ndarray,
    period: float,
) -> dict[str, Any]:
    """The summary's figures of a commanded joint motion (samples x joints):
    joint_limit_distance_min_rad, the smallest distance of a commanded joint to its
    position limit (rad, negative if past it), and oscillation_rate_max, the largest
    reversal rate of a commanded acceleration (1/s; the oscillation measure of
    systems/planning/acceleration_planner_watch.py at the given acceleration limits)."""
    lower, upper = position_limits
    distance = np.minimum(q - lower, upper - q)
    rates = ReversalRates(qdd, np.asarray(acceleration_limit, float), period)
    return {
        "joint_limit_distance_min_rad": round(float(distance.min(initial=np.inf)), 6),
        "oscillation_rate_max": round(float(rates.max(initial=0.0)), 3),
    }


@dataclass
class TrajectoryLogs:
    """Per-step logs of an arm's command, its measured joints and, where a planner commands
    it, the planner's state (PlannerState vectors, which hold qd and qdd)."""

    commanded: VectorLogSink
    measured: VectorLogSink
    planner: VectorLogSink | None

    def Clear(self, root_context: Context) -> None:
        """Empties the logs (a run starting again from a default context)."""
        for log in (self.commanded, self.measured, self.planner):
            if log is not None:
                log.FindMutableLog(root_context).Clear()

    def Samples(self, root_context: Context, period: float):
        """(times, q_cmd, qd_cmd, qdd_cmd, q_meas) one sample per control period (s, rad,
        rad/s, rad/s^2; samples x joints): the planner's own qd, qdd where it commands the
        arm, else finite differences of the sampled command."""
        log = self.commanded.FindLog(root_context)
        times, first = np.unique(log.sample_times(), return_index=True)
        grid = np.arange(0.0, times[-1] + period / 2, period) if times.size else times
        keep = first[np.searchsorted(times, grid - 1e-9).clip(0, max(times.size - 1, 0))]
        q_cmd = log.data()[:, keep].T
        q_meas = self.measured.FindLog(root_context).data()[:, keep].T
        if self.planner is None:
            qd, qdd = FiniteDifferences(grid, q_cmd)
            return grid, q_cmd, qd, qdd, q_meas
        states = self.planner.FindLog(root_context).data()[:, keep]
        return grid, q_cmd, states[6:12].T, states[12:18].T, q_meas


def AddTrajectoryLogs(
    builder: DiagramBuilder,
    commanded: OutputPort,
    measured: OutputPort,
    planner_state: OutputPort | None = None,
) -> TrajectoryLogs:
    """TrajectoryLogs of these ports, logged at every simulator step (periodic logs would
    race the planner's updates; Samples reduces them to one per control period)."""

    def Log(name: str, port: OutputPort) -> VectorLogSink:
        sink = builder.AddNamedSystem(name, VectorLogSink(port.size()))
        builder.Connect(port, sink.get_input_port())
        return sink

    planner = Log("trajectory_planner_log", planner_state) if planner_state else None
    return TrajectoryLogs(
        Log("trajectory_commanded_log", commanded),
        Log("trajectory_measured_log", measured),
        planner,
    )
