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
    contact, else from the start. Raises ConfigurationError (one line naming the bodies, or
    why the law cannot finish) when none is clear."""
    cartesian = _DryRun(planning, q0, max_time, collisions)
    if isinstance(cartesian, PlannerRoute):
        return cartesian
    reason, index = cartesian
    tried = []
    for start in dict.fromkeys([index, 0]):
        routed = _DryRun(planning.WithJointSpaceFrom(start), q0, max_time, collisions)
        if isinstance(routed, PlannerRoute):
            routed.joint_space_from = start
            return routed
        tried.append(f"through joint space from waypoint {start + 1}: {routed[0]}")
    raise ConfigurationError(f"the planner's dry run {reason}; {'; '.join(tried)}")


def _DryRun(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float, collisions: CellCollisions
) -> PlannerRoute | tuple[str, int]:
    """The law's dry run as a route if it ends clear of the cell, else why not and the
    waypoint (0-based) it headed for at its first contact (0 when it cannot finish)."""
    try:
        planned = RunPlanning(planning, q0, max_time)
    except PlanningError as e:
        return f"cannot finish the task: {e}", 0
    if planned.done_time < 0:
        return f"does not end within max_time {max_time} s", 0
    every = max(1, round(CONTACT_SAMPLE_S / planning.parameters.time_step))
    k = collisions.FirstContact(planned.q, every)
    if k is None:
        return PlannerRoute(planning, planned)
    a, b, depth = collisions.Contacts(planned.q[k])[0]
    waypoint = int(planned.index[k])
    reason = (
        f"collides at t = {planned.times[k]:.2f} s towards waypoint {waypoint + 1}: "
        f"{a} and {b} overlap by {1e3 * depth:.1f} mm"
    )
    return reason, waypoint
