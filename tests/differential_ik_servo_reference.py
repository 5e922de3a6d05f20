"""The numpy reference of the DifferentialIkServo's compiled kernel (csrc/servo_step.c):
the mathematics of systems/path_following/differential_ik_servo_math.py's docstring, written
plainly, which tests/test_differential_ik_servo_kernel.py holds the kernel to."""

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.systems.path_following.differential_ik_servo_math import (
    CENTRING_SPEED_SHARE,
    FEEDBACK_ACCELERATION_SHARE,
    MIN_DAMPING,
    JointLimits,
)


def PoseError(X_current: RigidTransform, X_desired: RigidTransform) -> np.ndarray:
    """[rotation vector; translation] (rad, m; in W) taking X_current to X_desired, from
    Drake's angle-axis of R_desired R_current'."""
    angle_axis = (X_desired @ X_current.inverse()).rotation().ToAngleAxis()
    w = angle_axis.axis() * angle_axis.angle()
    return np.concatenate([w, X_desired.translation() - X_current.translation()])


def CentringVelocity(q: np.ndarray, limits: JointLimits) -> np.ndarray:
    """Joint velocities (rad/s) toward the middle of each joint's range: 0 there,
    CENTRING_SPEED_SHARE of the speed limit at a limit, cubic in between."""
    middle = 0.5 * (limits.lower + limits.upper)
    half_range = np.maximum(0.5 * (limits.upper - limits.lower), 1e-9)
    x = np.clip((middle - q) / half_range, -1.0, 1.0)
    return CENTRING_SPEED_SHARE * limits.speed * x**3


def ServoStep(
    J: np.ndarray,
    error: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    period: float,
    limits: JointLimits,
    R_WT: np.ndarray,
    weights: np.ndarray,
    damping: float,
    gain: float,
    twist: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """(q_next, v_next, limited) as differential_ik_servo_math.ServoStep."""
    rotate = np.kron(np.eye(2), R_WT.T)  # W to T, rotation rows and translation rows
    W = np.diag(weights)
    A = W @ rotate @ J
    e, V = np.linalg.eigh(A.T @ A)
    lam2 = max(damping**2 - max(e[0], 0.0), MIN_DAMPING**2)

    def Solve(b: np.ndarray) -> np.ndarray:  # (A'A + lam2 I)^-1 b
        return V @ ((V.T @ b) / (e + lam2))

    v_c = Solve(lam2 * CentringVelocity(q, limits))
    dq = Solve(A.T @ (W @ rotate @ error))
    reach = np.max(np.abs(dq) / (FEEDBACK_ACCELERATION_SHARE * limits.acceleration))
    scale = min(gain, np.sqrt(2.0 / reach)) if reach > 0 else gain
    v_wanted = v_c + dq * scale
    if twist is not None:
        v_wanted = v_wanted + Solve(A.T @ (W @ rotate @ twist))
    speed_ratio = np.min(limits.speed / np.maximum(np.abs(v_wanted), 1e-300))
    if speed_ratio < 1.0:
        v_wanted = v_wanted * speed_ratio
    excess = np.max(np.abs(v_wanted - v) / (limits.acceleration * period))
    v_next = v + (v_wanted - v) / max(excess, 1.0)
    to_upper, to_lower = limits.upper - q, q - limits.lower
    a2 = 2 * limits.acceleration
    high = np.minimum(np.sqrt(a2 * np.maximum(to_upper, 0.0)), to_upper / period)
    low = np.maximum(-np.sqrt(a2 * np.maximum(to_lower, 0.0)), -to_lower / period)
    high = np.maximum(high, low)
    v_next = np.minimum(np.maximum(v_next, low), high)
    return q + v_next * period, v_next, bool(excess > 1.0 or speed_ratio < 1.0)
