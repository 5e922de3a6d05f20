"""The robust planner's route clear of the cell (RouteClearOfCell), kinematically: a seeded
large MZ04D move whose Cartesian line sweeps the upper arm into the wrist is routed through
joint space from that segment and ends clear, within 1 mm and the limits; a clear route
that does not end within max_time is kept; a UR10e task whose routes towards the planner's
IK solutions all fold the forearm onto the wrist goes towards another IK branch; a
Cartesian motion that oscillates (the watch's measure) is routed through joint space
before the robot runs it; a task no route of which passes is refused in one line."""

import numpy as np
import pytest

from guidedarm.diagrams.cli.command_compare_planners import LoadWaypointsScenario
from guidedarm.diagrams.studies.random_task_cell import RandomTaskCell
from guidedarm.diagrams.tasks.common.planner_route import RouteClearOfCell
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_math import RunPlanning
from guidedarm.systems.planning.acceleration_planner_watch import ReversalRates
from guidedarm.systems.planning.random_waypoint_tasks import MakeRandomWaypointTasks
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk


def _LargeTask(arm: str, index: int, overrides: list[str] | None = None):
    """Task `index` (0-based) of the seeded large set of `arm` (compare-planners --random 50
    --arm ARM --kind large): its scenario (with `overrides`), the robust law on its
    waypoints' IK solutions, the cell's collision checks and the task."""
    scenario = LoadWaypointsScenario(f"{arm}_waypoints", overrides or [])
    setup = MakePlannerSetup(scenario)
    cell = RandomTaskCell(scenario, setup)
    kinematics = setup.planning.kinematics
    task = MakeRandomWaypointTasks(kinematics, index + 1, 0, "large", cell.Clear)[index]
    margin = setup.planning.parameters.joint_limit_margin
    joints = SolveWaypointIk(kinematics, task.waypoints, task.q0, margin=margin)
    planning = setup.planning.WithWaypoints(task.waypoints, joints)
    return scenario, planning, cell.collisions, task


@pytest.fixture(scope="module")
def large_task():
    """MZ04D task 3: start and waypoint configurations clear of the cell, three waypoints."""
    return _LargeTask("mz04d", 2)


def test_a_colliding_cartesian_line_is_routed_through_joint_space(large_task):
    scenario, planning, collisions, task = large_task
    cartesian = RunPlanning(planning, task.q0, scenario.max_time)
    first = collisions.FirstContact(cartesian.q, 5)
    assert first is not None  # the Cartesian law's motion touches: link 2 against link 4
    assert cartesian.index[first] == 2

    route = RouteClearOfCell(planning, task.q0, scenario.max_time, collisions)
    assert route.joint_space_from == 2  # from the segment that touched, not from the start
    planned = route.planned
    assert collisions.FirstContact(planned.q, 1) is None  # every 2 ms sample clear
    kinematics = planning.kinematics
    end = int(np.searchsorted(planned.times, planned.done_time - 1e-9))
    assert 0 < planned.done_time < scenario.max_time
    error = np.linalg.norm(kinematics.Position(planned.q[end])[:3] - task.waypoints[-1, :3])
    assert error <= 1e-3
    lower, upper = kinematics.PositionLimits()
    assert np.all(planned.q >= lower) and np.all(planned.q <= upper)
    # up to the segment it re-routes, the run is the Cartesian law's motion
    handover = int(np.argmax(planned.index >= 2))
    np.testing.assert_array_equal(planned.q[: handover + 1], cartesian.q[: handover + 1])


def test_a_clear_route_that_does_not_end_within_max_time_is_kept(large_task):
    """With max_time 1 s no route ends; the Cartesian law is clear that far, so it is the
    route, and the run ends at max_time with its own verdict (exit 1), not refused."""
    _, planning, collisions, task = large_task
    route = RouteClearOfCell(planning, task.q0, 1.0, collisions)
    assert route.joint_space_from is None and route.planned.done_time < 0
    assert collisions.FirstContact(route.planned.q, 1) is None


def _EndsClearWithinLimits(planned, planning, collisions, task, max_time) -> None:
    """A route's dry run: every 2 ms sample clear of the cell, the task ended within
    max_time with the TCP within 1 mm of the last waypoint, no joint past its limits."""
    assert collisions.FirstContact(planned.q, 1) is None
    assert 0 < planned.done_time < max_time
    kinematics = planning.kinematics
    end = int(np.searchsorted(planned.times, planned.done_time - 1e-9))
    error = np.linalg.norm(kinematics.Position(planned.q[end])[:3] - task.waypoints[-1, :3])
    assert error <= 1e-3
    lower, upper = kinematics.PositionLimits()
    assert np.all(planned.q >= lower) and np.all(planned.q <= upper)


def test_a_task_whose_nearest_ik_solutions_touch_goes_towards_another_ik_branch():
    """Task 8 of the seeded UR10e large set: the Cartesian line and both joint-space routes
    towards the planner's IK solutions fold the forearm onto wrist 3; through joint space
    from the start towards another branch of waypoint 1 (the later waypoints solved
    nearest it) the task ends clear."""
    scenario, planning, collisions, task = _LargeTask("ur10e", 7)
    for start in (2, 0):
        routed = RunPlanning(planning.WithJointSpaceFrom(start), task.q0, scenario.max_time)
        assert collisions.FirstContact(routed.q, 5) is not None

    route = RouteClearOfCell(planning, task.q0, scenario.max_time, collisions)
    assert route.joint_space_from == 0
    joints = route.planning.joint_waypoints
    assert np.linalg.norm(joints[0] - planning.joint_waypoints[0]) > 0.5  # another branch
    kinematics = planning.kinematics
    for q, waypoint in zip(joints, task.waypoints, strict=True):  # each holds its pose
        np.testing.assert_allclose(kinematics.Position(q)[:3], waypoint[:3], atol=1e-6)
        assert not collisions.Contacts(q)
    _EndsClearWithinLimits(route.planned, planning, collisions, task, scenario.max_time)


def test_a_cartesian_motion_that_oscillates_is_routed_through_joint_space_before_motion():
    """Task 15 of the seeded UR10e large set: the Cartesian law's joint 4 reverses its
    acceleration more than 5 times a second (the watch would hand over only once the
    robot had run it); the route goes through joint space from that segment, and no
    joint oscillates by the measure."""
    scenario, planning, collisions, task = _LargeTask("ur10e", 14)
    limits, dt = np.asarray(planning.reversal_limits), planning.parameters.time_step
    cartesian = RunPlanning(planning, task.q0, scenario.max_time)
    bound = planning.parameters.max_reversal_rate
    assert ReversalRates(cartesian.qdd, limits, dt).max() > bound

    route = RouteClearOfCell(planning, task.q0, scenario.max_time, collisions)
    assert route.joint_space_from == 1
    assert ReversalRates(route.planned.qdd, limits, dt).max() <= bound
    _EndsClearWithinLimits(route.planned, planning, collisions, task, scenario.max_time)


def test_a_task_no_route_of_which_passes_is_refused_in_one_line():
    """With an oscillation bound of 0.5 /s every route of MZ04D task 3 oscillates (or
    touches): refused before motion, one line naming why for each route tried."""
    scenario, planning, collisions, task = _LargeTask("mz04d", 2, ["planner.max_reversal_rate=0.5"])
    with pytest.raises(ConfigurationError) as refused:
        RouteClearOfCell(planning, task.q0, scenario.max_time, collisions)
    message = str(refused.value)
    assert "\n" not in message
    assert message.startswith("the planner's dry run ")
    assert "through joint space from waypoint 1: " in message
    assert "other IK branches of waypoint 1 passes" in message


def test_a_joint_space_route_needs_the_robust_law_and_is_not_carried_to_a_new_task(large_task):
    _, planning, _, task = large_task
    routed = planning.WithJointSpaceFrom(1)
    assert routed.joint_space_from == 1 and planning.joint_space_from is None
    assert routed.WithWaypoints(task.waypoints).joint_space_from is None
    with pytest.raises(ConfigurationError, match="no waypoint 4"):
        planning.WithJointSpaceFrom(3)
    with pytest.raises(ConfigurationError, match="needs the robust mode"):
        planning.WithWaypoints(task.waypoints).WithJointSpaceFrom(0)  # no joint solutions
