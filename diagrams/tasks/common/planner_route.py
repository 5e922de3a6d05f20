"""The robust planner's route clear of the cell, chosen by kinematic dry runs before motion.

The law knows the joints' limits, not the cell: a Cartesian line of a few decimetres that
turns the tool by up to 90 deg can sweep the arm through its cell or itself although its
start and waypoint configurations are clear. RouteClearOfCell dry-runs the law (RunPlanning
from rest, sampled every CONTACT_SAMPLE_S) and judges its motion: it must not touch the cell
or the arm, must finish, and must not oscillate by the watch's measure (a joint's reversal
rate above planner.max_reversal_rate: the law would hand over, but only after the robot
ran the oscillating motion). Where it fails, the same task is dry-run handed over to joint
space (item 10 of docs/planner.md) from the segment of the first contact or oscillation,
then from the start: towards the waypoints' IK solutions, then towards other IK branches
of that segment's waypoint (WaypointIkBranches), nearest first. The first route that
passes is the route, else the task is refused before motion with one line naming the
bodies. A waypoints run and `compare-planners --random` both choose their route here.

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
from guidedarm.systems.planning.acceleration_planner_watch import ReversalRates
from guidedarm.systems.planning.waypoint_ik import WaypointIkBranches

CONTACT_SAMPLE_S = 0.01  # the dry run's check period (s): 5 planner steps at 500 Hz


@dataclass
class PlannerRoute:
    """The law a run uses (`planning`, with the joint solutions it heads for), its dry run
    from rest (`planned`) and the waypoint its joint-space route starts at
    (`joint_space_from`, 0-based; None: Cartesian)."""

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
    task ends or max_time, s) stays clear of the cell and the arm itself and does not
    oscillate: the Cartesian law, else the task routed through joint space from the
    waypoint it headed for at its first contact or oscillation, else from the start; each
    towards the planner's IK solutions, then towards the other IK branches of the waypoint
    the route starts at (nearest first). A route that ends is preferred; when none ends
    within max_time, the first clear one is the route (the run then ends at max_time, as
    its verdict says). Raises ConfigurationError (one line naming the bodies, or why the
    law cannot finish) when none is clear."""
    cartesian, reason, index = _DryRun(planning, q0, max_time, collisions)
    if cartesian is not None and cartesian.planned.done_time >= 0:
        return cartesian
    unfinished, tried = cartesian, []  # the first clear route that does not end
    starts = list(dict.fromkeys([index, 0]))
    for start in starts:  # the planner's own IK solutions: the least joint travel
        route, why = _RouteFrom(planning.WithJointSpaceFrom(start), start, q0, max_time, collisions)
        if route is not None and route.planned.done_time >= 0:
            return route
        unfinished = unfinished or route
        tried.append(f"through joint space from waypoint {start + 1}: {why}")
    for start in starts:  # other IK branches of the waypoint the route starts at
        branches = WaypointIkBranches(
            planning.kinematics,
            planning.waypoints,
            planning.joint_waypoints,
            q0,
            start,
            planning.parameters.joint_limit_margin,
        )
        for joints in branches:
            if any(collisions.Contacts(q) for q in joints[start:]):
                continue
            routed = planning.WithJointSpaceFrom(start, joints)
            route, _ = _RouteFrom(routed, start, q0, max_time, collisions)
            if route is not None and route.planned.done_time >= 0:
                return route
            unfinished = unfinished or route
        tried.append(f"none of {len(branches)} other IK branches of waypoint {start + 1} passes")
    if unfinished is not None:
        return unfinished
    raise ConfigurationError(f"the planner's dry run {reason}; {'; '.join(tried)}")


def _RouteFrom(
    planning: AccelerationPlanning,
    start: int,
    q0: np.ndarray,
    max_time: float,
    collisions: CellCollisions,
) -> tuple[PlannerRoute | None, str]:
    """The joint-space route `planning` (from waypoint `start`, 0-based) when its dry run
    passes (ended or not), else None; and why it does not pass."""
    route, why, _ = _DryRun(planning, q0, max_time, collisions)
    if route is not None:
        route.joint_space_from = start
    return route, why


def _DryRun(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float, collisions: CellCollisions
) -> tuple[PlannerRoute | None, str, int]:
    """The law's dry run: the route when it stays clear of the cell and does not oscillate
    (ended or not, see `planned.done_time`), else None; why it is not a finished route (""
    when it is); the waypoint (0-based) it headed for at its first contact or oscillation
    (0 without one)."""
    try:
        planned = RunPlanning(planning, q0, max_time)
    except PlanningError as e:
        return None, f"cannot finish the task: {e}", 0
    every = max(1, round(CONTACT_SAMPLE_S / planning.parameters.time_step))
    k = collisions.FirstContact(planned.q, every)
    if k is not None:
        a, b, depth = collisions.Contacts(planned.q[k])[0]
        waypoint = int(planned.index[k])
        reason = (
            f"collides at t = {planned.times[k]:.2f} s towards waypoint {waypoint + 1}: "
            f"{a} and {b} overlap by {1e3 * depth:.1f} mm"
        )
        return None, reason, waypoint
    oscillation = _OscillationOnset(planning, planned)
    if oscillation is not None:
        return None, *oscillation
    why = f"does not end within max_time {max_time} s" if planned.done_time < 0 else ""
    return PlannerRoute(planning, planned), why, 0


def _OscillationOnset(
    planning: AccelerationPlanning, planned: PlannedTrajectory
) -> tuple[str, int] | None:
    """Where the dry run's commanded q'' first oscillates by the watch's measure (a joint's
    reversal rate above planner.max_reversal_rate, counted on through a hand-over, as the
    run's summary counts it): why, and the waypoint (0-based) the law headed for; None if
    it never does (or without acceleration limits, which the measure needs)."""
    if planning.position_bounds is None:
        return None
    bound = planning.parameters.max_reversal_rate
    rates = ReversalRates(
        planned.qdd, np.asarray(planning.reversal_limits), planning.parameters.time_step
    )
    above = np.flatnonzero(rates.max(axis=1) > bound)
    if above.size == 0:
        return None
    k = int(above[0])
    joint = int(np.argmax(rates[k])) + 1
    waypoint = int(planned.index[k])
    reason = (
        f"oscillates at t = {planned.times[k]:.2f} s towards waypoint {waypoint + 1}: joint "
        f"{joint}'s commanded acceleration reverses more than {bound} times per second"
    )
    return reason, waypoint
