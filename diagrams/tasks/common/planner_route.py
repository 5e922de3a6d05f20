"""The robust planner's route clear of the cell, chosen by kinematic dry runs before motion.

The law knows the joints' limits, not the cell: a Cartesian line of a few decimetres that
turns the tool by up to 90 deg can sweep the arm through its cell or itself although its
start and waypoint configurations are clear. RouteClearOfCell dry-runs the law (RunPlanning
from rest, sampled every CONTACT_SAMPLE_S) and, where its motion touches the cell or the arm
or the law cannot finish, dry-runs the same task handed over to joint space (item 10 of
docs/planner.md, towards the waypoints' IK solutions) from the segment of the first contact,
then from the start; the first clear one is the route, else the task is refused before
motion with one line naming the bodies. A waypoints run and `compare-planners --random`
both choose their route here.

Units: rad, m, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    PlanningError,
    RunPlanning,
)
from guidedarm.systems.planning.acceleration_planner_state import PlannedTrajectory

CONTACT_SAMPLE_S = 0.01  # the dry run's check period (s): 5 planner steps at 500 Hz


@dataclass
class PlannerRoute:
    """The law a run uses (`planning`), its dry run from rest (`planned`) and the waypoint
    its joint-space route starts at (`joint_space_from`, 0-based; None: Cartesian)."""

    planning: AccelerationPlanning
    planned: PlannedTrajectory
    joint_space_from: int | None = None


def RouteClearOfCell(
    planning: AccelerationPlanning,
    q0: np.ndarray,
    max_time: float,
    collisions: CellCollisions,
) -> PlannerRoute:
    """The route of the robust law `planning` from rest at q0 (rad) whose dry run (until the
    task ends or max_time, s) stays clear of the cell and the arm itself: the Cartesian law,
    else the task routed through joint space from the waypoint it headed for at its first
    contact, else from the start. A route that ends is preferred; when none ends within
    max_time, the first clear one is the route (the run then ends at max_time, as its
    verdict says). Raises ConfigurationError (one line naming the bodies, or why the law
    cannot finish) when none is clear."""
    cartesian, reason, index = _DryRun(planning, q0, max_time, collisions)
    if cartesian is not None and cartesian.planned.done_time >= 0:
        return cartesian
    unfinished, tried = cartesian, []  # the first clear route that does not end
    for start in dict.fromkeys([index, 0]):
        routed, why, _ = _DryRun(planning.WithJointSpaceFrom(start), q0, max_time, collisions)
        if routed is not None:
            routed.joint_space_from = start
            if routed.planned.done_time >= 0:
                return routed
            unfinished = unfinished or routed
        tried.append(f"through joint space from waypoint {start + 1}: {why}")
    if unfinished is not None:
        return unfinished
    raise ConfigurationError(f"the planner's dry run {reason}; {'; '.join(tried)}")


def _DryRun(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float, collisions: CellCollisions
) -> tuple[PlannerRoute | None, str, int]:
    """The law's dry run: the route when it stays clear of the cell (ended or not, see
    `planned.done_time`), else None; why it is not a finished route ("" when it is); the
    waypoint (0-based) it headed for at its first contact (0 without one)."""
    try:
        planned = RunPlanning(planning, q0, max_time)
    except PlanningError as e:
        return None, f"cannot finish the task: {e}", 0
    every = max(1, round(CONTACT_SAMPLE_S / planning.parameters.time_step))
    k = collisions.FirstContact(planned.q, every)
    if k is None:
        why = f"does not end within max_time {max_time} s" if planned.done_time < 0 else ""
        return PlannerRoute(planning, planned), why, 0
    a, b, depth = collisions.Contacts(planned.q[k])[0]
    waypoint = int(planned.index[k])
    reason = (
        f"collides at t = {planned.times[k]:.2f} s towards waypoint {waypoint + 1}: "
        f"{a} and {b} overlap by {1e3 * depth:.1f} mm"
    )
    return None, reason, waypoint
