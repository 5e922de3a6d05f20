"""Rest-to-rest joint moves of the path follower: cruise speed, bounded acceleration."""

import numpy as np
import pytest

from guidedarm.systems.path_following.joint_moves import MotionLimits, PlanJointMove, Trapezoid


def _derivatives(move, dt=1e-3):
    t = np.arange(0.0, move.duration + 10 * dt, dt)
    q = np.array([move.Position(s) for s in t])
    v = np.diff(q, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    return q, v, a


@pytest.mark.parametrize("speed, accel", [(2.0, 20.0), (2.0, 3.0), (0.5, 100.0)])
def test_trapezoid_reaches_one_at_rest_within_its_bounds(speed, accel):
    profile = Trapezoid(speed, accel)
    t = np.linspace(0.0, profile.duration, 2001)
    s = np.array([profile.S(x) for x in t])
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(s) >= -1e-15)
    ds = np.diff(s) / np.diff(t)
    assert np.max(ds) <= speed + 1e-9
    dds = np.diff(ds) / np.diff(t)[1:]
    assert np.max(np.abs(dds)) <= accel * 1.01
    # Rest to rest: the first and last steps move only by the acceleration ramp.
    assert s[1] == pytest.approx(0.5 * accel * t[1] ** 2)
    # Continuous at the phase boundaries.
    assert np.max(np.abs(np.diff(s))) <= speed * (t[1] - t[0]) + 1e-12


def test_move_holds_the_tool_speed_and_the_joint_limits():
    limits = MotionLimits(
        tool_speed=0.05, max_joint_speed=1.0, tool_acceleration=0.5, max_joint_acceleration=5.0
    )
    waypoints = [
        np.zeros(6),
        np.array([0.02, 0.01, 0, 0, 0, 0.0]),
        np.array([0.02, 0, 0, 0, 0, 1.5]),
    ]
    tool = [np.zeros(3), np.array([0.015, 0, 0]), np.array([0.015, 0, 0.001])]
    move = PlanJointMove(waypoints, tool, limits)
    q, v, a = _derivatives(move)
    np.testing.assert_allclose(q[0], waypoints[0])
    np.testing.assert_allclose(q[-1], waypoints[-1])
    # Segment 1: 15 mm at 50 mm/s with 0.1 s ramps; segment 2: joint 6 turns 1.5 rad at
    # 1 rad/s with 5 rad/s^2.
    assert move.profiles[0].duration == pytest.approx(0.015 / 0.05 + 0.1)
    assert move.profiles[1].duration == pytest.approx(1.5 / 1.0 + 1.0 / 5.0)
    assert np.max(np.abs(v)) <= 1.0 + 1e-6
    assert np.max(np.abs(a)) <= 5.0 * 1.01
    # The arm stops at the middle waypoint.
    k = round(move.profiles[0].duration / 1e-3)
    np.testing.assert_allclose(q[k], waypoints[1], atol=1e-9)
    assert np.max(np.abs(v[k - 1])) < 0.01


def test_segments_without_joint_motion_are_dropped():
    q = np.ones(6)
    move = PlanJointMove([q, q, q + 0.1], [np.zeros(3)] * 3, MotionLimits())
    assert len(move.profiles) == 1
    np.testing.assert_allclose(move.Position(move.duration + 1.0), q + 0.1)
