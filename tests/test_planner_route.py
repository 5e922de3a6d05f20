"""The robust planner's route clear of the cell (RouteClearOfCell), kinematically: a seeded
large MZ04D move whose Cartesian line sweeps the upper arm into the wrist is routed through
joint space from that segment and ends clear, within 1 mm and the limits; a clear route
that does not end within max_time is kept; a task every route of which touches is refused
in one line."""

import numpy as np
import pytest

from guidedarm.diagrams.cli.command_compare_planners import LoadWaypointsScenario
from guidedarm.diagrams.studies.random_task_cell import RandomTaskCell
from guidedarm.diagrams.tasks.common.planner_route import RouteClearOfCell
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_math import RunPlanning
from guidedarm.systems.planning.random_waypoint_tasks import MakeRandomWaypointTasks
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk


def _LargeTask(arm: str, index: int):
    """Task `index` (0-based) of the seeded large set of `arm` (compare-planners --random 50
    --arm ARM --kind large): its scenario, the robust law on its waypoints' IK solutions,
    the cell's collision checks and the task."""
    scenario = LoadWaypointsScenario(f"{arm}_waypoints", [])
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


def test_a_task_every_route_of_which_touches_is_refused_in_one_line():
    """Task 8 of the seeded UR10e large set: the Cartesian line and both joint-space routes
    fold the forearm onto wrist 3."""
    scenario, planning, collisions, task = _LargeTask("ur10e", 7)
    with pytest.raises(ConfigurationError) as refused:
        RouteClearOfCell(planning, task.q0, scenario.max_time, collisions)
    message = str(refused.value)
    assert "\n" not in message
    assert message.startswith("the planner's dry run collides at t = ")
    assert message.count("ur10e::forearm_link and ur10e::wrist_3_link overlap by") == 3
    assert "through joint space from waypoint 1" in message


def test_a_joint_space_route_needs_the_robust_law_and_is_not_carried_to_a_new_task(large_task):
    _, planning, _, task = large_task
    routed = planning.WithJointSpaceFrom(1)
    assert routed.joint_space_from == 1 and planning.joint_space_from is None
    assert routed.WithWaypoints(task.waypoints).joint_space_from is None
    with pytest.raises(ConfigurationError, match="no waypoint 4"):
        planning.WithJointSpaceFrom(3)
    with pytest.raises(ConfigurationError, match="needs the robust mode"):
        planning.WithWaypoints(task.waypoints).WithJointSpaceFrom(0)  # no joint solutions
