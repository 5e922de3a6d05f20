"""Path-follower moves through Pająk's acceleration-level planner (motion: planner)."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.diagrams.tasks.path_following.builder import MakePlannerMoves
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.planning.acceleration_planner_math import PlanningError


@pytest.fixture(scope="module")
def planner_moves(tmp_path_factory):
    _, scenario, _ = LoadScenario("path_following", ["motion=planner"])
    setup = MakeSetup(scenario, tmp_path_factory.mktemp("planner"))
    return setup, setup.solver, setup.mount, MakePlannerMoves(setup)


def test_a_retrace_and_turn_ends_on_the_ik_pose_within_the_limits(planner_moves):
    """Back 15 mm to a stop, then a 20 deg turn in place: the move rests at the stop, ends
    within the planner's 1 mm of the IK solution's tool pose, and no sample exceeds the
    joint speed and acceleration limits."""
    setup, solver, mount, moves = planner_moves
    q0 = setup.q_start
    X_WT0 = mount.ToolPose(solver.ForwardKinematics(q0))
    n = X_WT0.rotation().matrix()[:, 0]
    ahead = solver.Solve(mount.GripperPose(_Shifted(X_WT0, 0.015 * n)), q0)
    turned = solver.Solve(mount.GripperPose(_Turned(X_WT0, np.radians(20))), q0)
    assert ahead.success and turned.success
    move = moves([ahead.q, q0, turned.q], [None] * 3)
    np.testing.assert_allclose(move.Position(0.0), ahead.q)
    X_end = mount.ToolPose(solver.ForwardKinematics(move.goal))
    X_goal = mount.ToolPose(solver.ForwardKinematics(turned.q))
    assert np.linalg.norm(X_end.translation() - X_goal.translation()) <= 0.001
    dt = np.diff(move.times)
    qd = np.diff(move.q, axis=0) / dt[:, None]
    qdd = np.diff(qd, axis=0) / dt[1:, None]
    assert np.max(np.abs(qd)) <= setup.limits.max_joint_speed + 1e-6
    assert np.max(np.abs(qdd)) <= setup.limits.max_joint_acceleration + 1e-6
    # It passes the middle stop (the start pose) on the way.
    assert np.min(np.max(np.abs(move.q - q0), axis=1)) < 0.002


def test_an_unreachable_segment_is_a_planning_error(planner_moves):
    setup, _, _, moves = planner_moves
    far = setup.q_start + np.array([0.0, 0.0, 0.0, 0.0, 2.0, 0.0])
    moves.max_time = 0.5
    try:
        with pytest.raises(PlanningError, match=r"did not reach its target within 0\.5 s"):
            moves([setup.q_start, far], [None] * 2)
    finally:
        moves.max_time = 10.0


def _Shifted(X, offset):
    return RigidTransform(X.rotation(), X.translation() + offset)


def _Turned(X, yaw):
    return RigidTransform(RotationMatrix.MakeZRotation(yaw) @ X.rotation(), X.translation())
