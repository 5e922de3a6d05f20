"""The waypoints' IK (SolveWaypointIk) at the edge of the joint limits, without a Diagram."""

import numpy as np
import pytest

from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import PoseError
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk, WaypointPose

MARGIN = 0.01


@pytest.fixture(scope="module")
def kinematics():
    return MakePlannerSetup(LoadScenario("rover_arm_waypoints", [])[1]).planning.kinematics


def _Miss(kinematics, q: np.ndarray, waypoint: np.ndarray) -> float:
    X_BT = WaypointPose(waypoint)
    kin = kinematics.Evaluate(q, np.zeros(6), analytic=False)
    return float(np.abs(PoseError(kin, X_BT.translation(), X_BT.rotation().matrix())).max())


def test_a_pose_whose_near_solution_is_a_hair_past_the_limit_gets_an_exact_one_inside(
    kinematics,
):
    """The panel's limit edge on the rover arm: near the wrist singularity (q5 = -0.02) the
    near branch holds the pose only with J6 3 mrad past its lower limit less the margin,
    and the solver's approximate solution inside misses it by 4e-5 rad, more than the
    panel moves' 1e-4 tolerance allows to hand over to. The IK returns the exact solution of
    the flipped wrist instead (J4 and J6 half a turn away, q5 = +0.02), inside the limits."""
    lower, upper = kinematics.PositionLimits()
    q_edge = np.array([0.0, -1.5, 1.48, 2.94, -0.02, lower[5] + MARGIN - 0.003])
    waypoint = kinematics.Position(q_edge)
    q_start = q_edge + np.array([-0.1, -0.35, 0.33, -1.46, 0.19, 1.47])
    q = SolveWaypointIk(kinematics, waypoint[np.newaxis], q_start, margin=MARGIN)[0]
    assert _Miss(kinematics, q, waypoint) <= 1e-6
    assert np.all(q >= lower + MARGIN) and np.all(q <= upper - MARGIN)
    assert q[4] == pytest.approx(0.02, abs=1e-3) and q[3] == pytest.approx(-0.2016, abs=1e-3)


def test_a_pose_reachable_only_past_a_limit_is_refused_in_one_line(kinematics):
    """J2 0.4 rad past its upper limit: no branch holds the pose within the limits, and the
    refusal names the waypoint and says so, rather than returning a solution that misses."""
    upper = kinematics.PositionLimits()[1]
    q_goal = np.array([0.0, upper[1] + 0.4, 1.0, 0.0, 0.5, 0.0])
    waypoint = kinematics.Position(q_goal)
    with pytest.raises(ConfigurationError, match=r"^waypoint 1 .* out of reach") as refusal:
        SolveWaypointIk(kinematics, waypoint[np.newaxis], np.zeros(6), margin=MARGIN)
    assert "\n" not in str(refusal.value)
