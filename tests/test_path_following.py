"""The paper's path-following equations (1)-(26), long/short steps, recovery and end."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.path_follower_math import (
    FollowerConfig,
    FollowerMemory,
    FollowStep,
    GiveUpDirection,
    OrientationFromVector,
    Rotation,
    ToolMount,
)

PARAMS = FollowerConfig(long_step=0.015, short_step=0.010, lost_limit=2).Resolved("grid")


def test_rotation_is_z_y_x():
    rng = np.random.default_rng(0)
    for roll, pitch, yaw in rng.uniform(-3, 3, size=(20, 3)):
        np.testing.assert_allclose(
            Rotation(roll, pitch, yaw),
            RollPitchYaw(roll, pitch, yaw).ToRotationMatrix().matrix(),
            atol=1e-12,
        )


def test_tool_pose_from_gripper_pose_eq_23_26():
    mount = ToolMount(0.1597, math.pi, 0.0, -math.pi / 4)
    X_WG = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.3, 0.1, 0.4])
    X_WT = mount.ToolPose(X_WG)
    # O = O_c + R_c z l_e, and the tool z axis points back at the gripper (roll pi).
    np.testing.assert_allclose(
        X_WT.translation(), X_WG.translation() + X_WG.rotation().matrix()[:, 2] * 0.1597
    )
    np.testing.assert_allclose(
        X_WT.rotation().matrix()[:, 2], -X_WG.rotation().matrix()[:, 2], atol=1e-12
    )
    back = mount.GripperPose(X_WT)
    np.testing.assert_allclose(back.GetAsMatrix4(), X_WG.GetAsMatrix4(), atol=1e-12)
    assert ToolMount.FromTransform(
        RigidTransform(RollPitchYaw(math.pi, 0, -math.pi / 4), [0, 0, 0.1597])
    ).l_e == pytest.approx(0.1597)
    with pytest.raises(ConfigurationError, match="not on the gripper z axis"):
        ToolMount.FromTransform(RigidTransform([0.01, 0, 0.1]))


def test_orientation_from_vector_eq_20_22():
    w_a = np.array([1.0, 1.0, -math.sqrt(2.0)])
    rpy = RollPitchYaw(OrientationFromVector(w_a))
    assert rpy.yaw_angle() == pytest.approx(math.pi / 4)
    assert rpy.pitch_angle() == pytest.approx(math.pi / 4)  # going down: positive pitch (21)
    assert rpy.roll_angle() == pytest.approx(0.0, abs=1e-12)


def test_a_rolled_tool_keeps_its_roll_in_every_step_and_retry():
    """tool_roll_deg: x_T along the step direction as at roll 0, turned by the roll about
    it; the stop-and-go steps, lost steps and retries keep it."""
    roll = math.radians(-45.0)
    w_a = np.array([1.0, 0.5, -0.2])
    plain, rolled = OrientationFromVector(w_a), OrientationFromVector(w_a, roll)
    np.testing.assert_allclose(rolled.matrix()[:, 0], plain.matrix()[:, 0], atol=1e-12)
    rpy, rpy0 = RollPitchYaw(rolled), RollPitchYaw(plain)
    assert rpy.roll_angle() == pytest.approx(roll)
    assert (rpy.pitch_angle(), rpy.yaw_angle()) == pytest.approx(
        (rpy0.pitch_angle(), rpy0.yaw_angle())
    )
    X = RigidTransform(RollPitchYaw(roll, 0.0, 0.3), [0.3, 0.0, 0.01])
    memory = FollowerMemory.Start(X, PARAMS, roll)
    rolls, retries = [], []
    for S_T in [np.array([0.0, 0.01, -0.005]), None, None, None, None]:
        result = FollowStep(X, S_T, False, memory, PARAMS)
        X, memory = result.X_WT_next, result.memory
        rolls.append(RollPitchYaw(X.rotation()).roll_angle())
        retries.append(result.info.get("recovery"))
    assert retries == [None, None, None, 1, None]  # lost past lost_limit: the first retry
    np.testing.assert_allclose(rolls, roll, atol=1e-12)


def _tool(yaw=0.0, p=(0.3, 0.0, 0.1)):
    return RigidTransform(RollPitchYaw(0.0, 0.0, yaw), list(p))


def test_long_step_toward_an_offset_detection_eq_9_13_17():
    seed_params = FollowerConfig(
        long_step=0.015, short_step=0.010, steering="paper", rotation_reduction=0.3
    ).Resolved("grid")
    X_WT = _tool()
    memory = FollowerMemory(np.array([0.285, 0.0, 0.1]), X_WT)  # O' 15 mm behind
    S_T = np.array([0.0, 0.022, 0.0])  # hose seen at the +y grid point
    result = FollowStep(X_WT, S_T, False, memory, seed_params)
    t = np.array([0.015, 0.0, 0.0])
    m = np.array([0.0, 0.022, 0.0])
    w = t + m
    np.testing.assert_allclose(
        result.X_WT_next.translation(), [0.3, 0.0, 0.1] + w / np.linalg.norm(w) * 0.015
    )
    w_a = np.array([1.0, 0.0, 0.0]) * 0.015 + m * 0.3
    assert RollPitchYaw(result.X_WT_next.rotation()).yaw_angle() == pytest.approx(
        math.atan2(w_a[1], w_a[0])
    )
    assert result.long_step
    np.testing.assert_allclose(result.memory.O_prime, [0.3, 0.0, 0.1])


def test_centre_only_is_a_short_step_along_the_tool_axis_eq_14():
    X_WT = _tool(yaw=0.5)
    memory = FollowerMemory.Start(X_WT, PARAMS)
    result = FollowStep(X_WT, np.zeros(3), True, memory, PARAMS)
    n = X_WT.rotation().matrix()[:, 0]
    np.testing.assert_allclose(result.X_WT_next.translation(), X_WT.translation() + n * 0.010)
    assert not result.long_step


def test_lost_then_recovery_then_end():
    X_seen = _tool()
    memory = FollowerMemory.Start(X_seen, PARAMS)
    result = FollowStep(X_seen, np.zeros(3), True, memory, PARAMS)
    X, memory = result.X_WT_next, result.memory
    O_prime = memory.O_prime.copy()
    for k in range(PARAMS.lost_limit):  # straight on, O' kept (the paper's S = O case)
        result = FollowStep(X, None, False, memory, PARAMS)
        np.testing.assert_allclose(result.memory.O_prime, O_prime)
        assert result.memory.lost == k + 1
        X, memory = result.X_WT_next, result.memory
    # Next loss: back to the last detecting pose, turned; each unreachable or lost retry
    # moves on to the next turn (yaw +, yaw -, pitch up), then the path has ended.
    result = FollowStep(X, None, False, memory, PARAMS)
    turns = []
    while not result.ended:
        np.testing.assert_allclose(result.X_WT_next.translation(), X_seen.translation())
        rpy = RollPitchYaw(result.X_WT_next.rotation())
        turns.append((round(math.degrees(rpy.yaw_angle())), round(math.degrees(rpy.pitch_angle()))))
        result = GiveUpDirection(result.X_WT_next, result.memory, PARAMS)
    assert turns == [(20, 0), (-20, 0), (0, -20)]


def test_a_retry_that_finds_the_hose_again_is_a_recovery():
    X_seen = _tool()
    memory = FollowerMemory.Start(X_seen, PARAMS)
    memory = FollowStep(X_seen, np.zeros(3), True, memory, PARAMS).memory
    retry = GiveUpDirection(X_seen, memory, PARAMS)
    assert retry.memory.recovery == 1
    # Seen again at the retry pose itself: not yet a recovery.
    again = FollowStep(retry.X_WT_next, np.zeros(3), True, retry.memory, PARAMS)
    assert again.memory.recoveries == 0 and again.memory.recovery == 1
    moved = FollowStep(again.X_WT_next, np.zeros(3), True, again.memory, PARAMS)
    moved = FollowStep(moved.X_WT_next, np.zeros(3), True, moved.memory, PARAMS)
    assert moved.memory.recoveries == 1 and moved.memory.recovery == 0


def test_lost_again_where_it_was_lost_before_is_the_end():
    """After a recovery, losing the hose within two long steps of the previous loss ends
    the run (the retries only glimpse the hose's end); farther on, retries start again."""

    def lose(X, memory):
        for _ in range(PARAMS.lost_limit + 1):
            result = FollowStep(X, None, False, memory, PARAMS)
            X, memory = result.X_WT_next, result.memory
        return result

    def follow(X, memory, steps):
        for _ in range(steps):
            result = FollowStep(X, np.zeros(3), True, memory, PARAMS)
            X, memory = result.X_WT_next, result.memory
        return X, memory

    X, memory = follow(_tool(), FollowerMemory.Start(_tool(), PARAMS), 1)
    retry = lose(X, memory)
    assert retry.info == {"recovery": 1}
    X, memory = follow(retry.X_WT_next, retry.memory, 3)  # last seen 20 mm past the loss
    assert memory.recoveries == 1 and memory.recovery == 0
    assert lose(X, memory).ended
    X, memory = follow(X, memory, 2)  # last seen 40 mm past it: beyond two long steps
    assert lose(X, memory).info == {"recovery": 1}


def test_params_are_checked_and_resolved():
    assert FollowerConfig().Resolved("ranging").steering == "centring"
    assert FollowerConfig().Resolved("grid").rotation_reduction == 0.3
    with pytest.raises(ConfigurationError, match="key 'estimator': 'lidar' is not one of"):
        FollowerConfig().Resolved("lidar")
    with pytest.raises(ConfigurationError, match="rotation_reduction"):
        FollowerConfig(rotation_reduction=1.5).Resolved("grid")
