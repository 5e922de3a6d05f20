"""The cell in the planners' random comparison (`guidedarm compare-planners --random`).

The random reachable tasks are made by kinematics alone; a station run of one of them
would first check it against the arm's cell (CheckCellBeforeMotion). RandomTaskCell does
the same cheaply, without a simulation: it draws tasks clear of the cell (a start or a
waypoint configuration that collides is drawn again), refuses a task whose start or one of
the planner's waypoint IK solutions collides (the run would refuse it before motion; the
robust planner's route is chosen by RouteClearOfCell, as in a run), and
samples every planner's commanded trajectory every CONTACT_SAMPLE_S against the cell and
the arm itself. CellFigures adds the table's columns per planner: tasks refused, tasks
ending within 1 mm, tasks whose motion touched the cell, and the largest oscillation rate
(the planner watch's measure on the commanded accelerations).

Units: rad, m, s.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions, ModelNames
from guidedarm.diagrams.tasks.common.planner_route import CONTACT_SAMPLE_S
from guidedarm.diagrams.tasks.common.trajectory_csv import JointMotionMetrics
from guidedarm.diagrams.tasks.waypoints import PlannerSetup, WaypointsScenario
from guidedarm.systems.planning.planner_baselines import JointTrajectory
from guidedarm.systems.planning.random_waypoint_tasks import RandomWaypointTask
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk

END_TOLERANCE_M = 1e-3


class RandomTaskCell:
    """The cell of a waypoints scenario (its station, arm and the controller plant's
    tools) for random tasks planned with `setup`."""

    def __init__(self, scenario: WaypointsScenario, setup: PlannerSetup) -> None:
        self.setup = setup
        self.collisions = CellCollisions(scenario.station, scenario.arm, ModelNames(setup.plant))

    def Clear(self, q: np.ndarray) -> bool:
        """Whether the arm at joint positions q (rad) is clear of its cell and itself."""
        return not self.collisions.Contacts(q)

    def Refused(self, task: RandomWaypointTask) -> bool:
        """Whether the task's start or a waypoint's joint solution (the planner's own IK,
        within its joint limit margin) collides: a run refuses it before motion."""
        planning = self.setup.planning
        joints = SolveWaypointIk(
            planning.kinematics,
            task.waypoints,
            task.q0,
            margin=planning.parameters.joint_limit_margin,
        )
        return not all(self.Clear(q) for q in [task.q0, *joints])

    def Touches(self, trajectory: JointTrajectory) -> bool:
        """Whether a commanded trajectory, sampled every CONTACT_SAMPLE_S (s), brings the
        arm into its cell or itself."""
        period = self.setup.planning.parameters.time_step  # every planner's sample period
        every = max(1, round(CONTACT_SAMPLE_S / period))
        samples = np.vstack([trajectory.q[::every], trajectory.q[-1:]])
        return self.collisions.CountContacts(samples) > 0


def CellFigures(
    cell: RandomTaskCell,
    tasks: Sequence[RandomWaypointTask],
    refused: Sequence[bool],
    trajectories: Sequence[JointTrajectory | None],
) -> dict[str, Any]:
    """One planner's cell columns over the tasks (its trajectory per task, None where it
    found none): `refused` tasks, and over the others the tasks whose commanded motion
    ends within END_TOLERANCE_M (m) of the last waypoint (`within_1mm`), those whose motion
    touches the cell or the arm itself (`contacts`), and the largest oscillation rate
    (`oscillation_rate_max`, 1/s: sign reversals of q'' beyond half its limit, the watch's
    measure at the scenario's acceleration limits)."""
    setup = cell.setup
    kinematics = setup.planning.kinematics
    within = contacts = 0
    oscillation = 0.0
    for task, is_refused, trajectory in zip(tasks, refused, trajectories, strict=True):
        if is_refused or trajectory is None:
            continue
        end = np.linalg.norm(kinematics.Position(trajectory.q[-1])[:3] - task.waypoints[-1, :3])
        within += bool(end <= END_TOLERANCE_M)
        contacts += cell.Touches(trajectory)
        motion = JointMotionMetrics(
            trajectory.q,
            trajectory.qdd,
            kinematics.PositionLimits(),
            setup.acceleration_limit,
            setup.planning.parameters.time_step,
        )
        oscillation = max(oscillation, motion["oscillation_rate_max"])
    return {
        "refused": int(sum(refused)),
        "within_1mm": within,
        "contacts": contacts,
        "oscillation_rate_max": oscillation,
    }
