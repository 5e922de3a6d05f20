"""The DifferentialIkServo's compiled kernel (csrc/servo_step.c) against its numpy
reference (tests/differential_ik_servo_reference.py) on random inputs, to 1e-12."""

import differential_ik_servo_reference as reference
import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from guidedarm.systems.path_following.differential_ik_servo_math import (
    JointLimits,
    PoseError,
    PoseErrorOfRows,
    Rows,
    ServoPeriod,
    ServoStep,
    StoppingPositions,
)


def test_pose_error_equals_drakes_angle_axis():
    """Random pose pairs, from nearly equal to half a turn apart (the rotation vector's
    length is the angle, up to pi)."""
    rng = np.random.default_rng(2)
    for scale in (1e-9, 1e-4, 0.1, 1.0, 3.0, 3.14):
        for _ in range(200):
            X = RigidTransform(RollPitchYaw(*rng.uniform(-np.pi, np.pi, 3)), rng.normal(size=3))
            axis = rng.normal(size=3)
            turn = (
                RotationMatrix.MakeFromOneVector(axis, 2)
                @ RotationMatrix.MakeZRotation(scale * rng.uniform(0.5, 1.0))
                @ RotationMatrix.MakeFromOneVector(axis, 2).inverse()
            )
            Y = RigidTransform(turn @ X.rotation(), X.translation() + rng.normal(size=3))
            np.testing.assert_allclose(
                PoseError(X, Y), reference.PoseError(X, Y), rtol=0, atol=1e-12
            )


@pytest.mark.parametrize("n", [6, 7, 5])
def test_servo_step_equals_the_reference(n):
    """Random Jacobians, errors (small to large), joints near and far from their limits,
    speeds and accelerations that bind or not, weights, damping near and away from a
    singularity, with and without feedforward: the same `limited`, and the same q_next and
    v_next to 1e-12, near a singularity to 1e-16 times the condition number of the damped
    normal matrix (the two eigen-decompositions round differently, and the solve amplifies
    that by its condition)."""
    rng = np.random.default_rng(n)
    limited = []
    for k in range(600):
        J = rng.normal(size=(6, n))
        if k % 3 == 0:  # near a singularity: the damping acts
            J[:, -1] = J[:, 0] * rng.uniform(-1, 1) + 1e-3 * rng.normal(size=6)
        lower = -rng.uniform(1.0, 3.0, n)
        upper = rng.uniform(1.0, 3.0, n)
        limits = JointLimits(lower, upper, rng.uniform(0.5, 2.0, n), rng.uniform(2.0, 10.0, n))
        q = rng.uniform(lower, upper)
        v = rng.uniform(-1, 1, n) * limits.speed * (k % 4 != 0)  # at rest, 1 in 4
        error = rng.normal(size=6) * 10.0 ** rng.uniform(-6, 0)
        twist = rng.normal(size=6) * 0.1 if k % 2 else None
        R = RotationMatrix(RollPitchYaw(*rng.uniform(-np.pi, np.pi, 3))).matrix()
        weights = rng.uniform(0.05, 1.0, 6)
        args = (J, error, q, v, 0.008, limits, R, weights, rng.uniform(1e-3, 0.05), 20.0, twist)
        q_next, v_next, was_limited = ServoStep(*args)
        q_ref, v_ref, ref_limited = reference.ServoStep(*args)
        e = np.linalg.eigvalsh((J * weights[:, None]).T @ (J * weights[:, None]))
        tolerance = max(1e-12, 1e-16 * e[-1] / max(args[8] ** 2 - max(e[0], 0), 1e-6))
        np.testing.assert_allclose(v_next, v_ref, rtol=0, atol=tolerance)
        np.testing.assert_allclose(q_next, q_ref, rtol=0, atol=tolerance)
        assert was_limited == ref_limited
        limited.append(was_limited)
    assert 20 <= sum(limited) <= len(limited) - 20  # both branches are exercised


def test_servo_step_refuses_a_non_finite_jacobian():
    limits = JointLimits(-np.ones(6), np.ones(6), np.ones(6), np.ones(6))
    with pytest.raises(ValueError, match="not finite"):
        ServoStep(
            np.full((6, 6), np.nan),
            np.zeros(6),
            np.zeros(6),
            np.zeros(6),
            0.008,
            limits,
            np.eye(3),
            np.ones(6),
            0.01,
            20.0,
        )


def test_the_servo_period_is_its_parts_in_one_call():
    """ServoPeriod (the servo's period in one kernel call) gives exactly what its parts give
    called one by one: ServoStep on PoseErrorOfRows with the feedforward twist from the
    previous target (none for a NaN previous or feedforward 0), then StoppingPositions."""
    rng = np.random.default_rng(9)
    for k in range(300):
        n = 6
        J = rng.normal(size=(6, n))
        lower, upper = -rng.uniform(1.0, 3.0, n), rng.uniform(1.0, 3.0, n)
        limits = JointLimits(lower, upper, rng.uniform(0.5, 2.0, n), rng.uniform(2.0, 10.0, n))
        q, v = rng.uniform(lower, upper), rng.uniform(-1, 1, n) * limits.speed
        poses = [
            RigidTransform(RollPitchYaw(*rng.uniform(-np.pi, np.pi, 3)), rng.normal(size=3))
            for _ in range(3)
        ]
        M_WT, M_WD, previous = (Rows(X) for X in poses)
        previous = previous.ravel() if k % 3 else np.full(12, np.nan)
        feedforward = 0.0 if k % 5 == 0 else rng.uniform(10.0, 200.0)
        weights = rng.uniform(0.05, 1.0, 6)
        damping = rng.uniform(1e-3, 0.05)
        q_next, v_next = np.empty(n), np.empty(n)
        limited, stop = ServoPeriod(
            J, M_WT, M_WD, previous, feedforward, q, v, 0.008, limits, weights, damping, 20.0,
            q_next, v_next,
        )  # fmt: skip
        twist = None
        if feedforward and not np.isnan(previous[0]):
            twist = PoseErrorOfRows(previous, M_WD) * feedforward
        error = PoseErrorOfRows(M_WT, M_WD)
        args = (J, error, q, v, 0.008, limits, M_WT[:, :3], weights, damping, 20.0, twist)
        q_ref, v_ref, limited_ref = ServoStep(*args)
        assert limited == limited_ref
        assert q_next.tolist() == q_ref.tolist() and v_next.tolist() == v_ref.tolist()
        assert stop == StoppingPositions(q_ref, v_ref, limits)
