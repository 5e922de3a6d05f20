"""Mathematics of the DifferentialIkServo: one period of resolved-rate control within
joint limits (rad, rad/s, rad/s^2; frames: world W, the controlled frame T).

    V = [w; v] = the target's own velocity (its change over the last period)
                 + gain x pose error of T (axis-angle, translation; in W)
    v_next = argmin |W (J v - V)|^2 + damping^2 |v|^2, W = diag(weights) on the rows of
             J and V expressed in T (roll about x_T, pitch, yaw, then x, y, z)
    v_next = v_prev + a (clip(v_wanted, speed limits) - v_prev), a in [0, 1] the largest
    that keeps every joint within v_prev +- acceleration x period; then clipped so that
    q + v_next period stays within the position limits
    q_next = q + v_next period

Drake's DoDifferentialInverseKinematics keeps J v_next parallel to V; with acceleration
limits that has no solution whenever the error turns faster than the joints may (each
noisy correction of the target), and the arm stalls. The damped least squares above always
has one: when a limit binds, the frame's velocity bends a little instead. The gain (1/s)
makes the error decay smoothly; an error / period (dead-beat) demand saturates the
acceleration limits at every correction and rings.
"""

import numpy as np
from pydrake.math import RigidTransform


def PoseError(X_current: RigidTransform, X_desired: RigidTransform) -> np.ndarray:
    """[rotation vector; translation] (rad, m; in W) taking X_current to X_desired."""
    R_error = X_desired.rotation().multiply(X_current.rotation().inverse())
    angle_axis = R_error.ToAngleAxis()
    w = angle_axis.axis() * angle_axis.angle()
    return np.concatenate([w, X_desired.translation() - X_current.translation()])


def ServoStep(
    J: np.ndarray,
    V: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    period: float,
    max_speed: np.ndarray,
    max_acceleration: np.ndarray,
    q_limits: tuple[np.ndarray, np.ndarray],
    R_WT: np.ndarray,
    weights: np.ndarray,
    damping: float,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """(q_next, v_next, limited): one period (module docstring); J is the 6 x n spatial
    velocity Jacobian of T in W at q, V the wanted spatial velocity of T; limited: whether
    a limit changed v_next. R_WT: T's orientation (3 x 3)."""
    n = J.shape[1]
    to_T = np.kron(np.eye(2), R_WT.T) * np.asarray(weights, float)[:, None]
    J_T, V_T = to_T @ J, to_T @ V
    v_wanted = np.linalg.solve(J_T.T @ J_T + damping**2 * np.eye(n), J_T.T @ V_T)
    # The wanted velocity is clipped to the speed limits, then the change of v is scaled
    # (not clipped joint by joint) into the acceleration limits, so that the frame's
    # acceleration keeps its direction: clipping each joint bent it, and in a fast turn
    # the bent motion fed back into a growing error. (Scaling for the speed limits too
    # would freeze every joint while one is at its limit.)
    dv = np.clip(v_wanted, -max_speed, max_speed) - v
    step = max_acceleration * period
    need = np.abs(dv)
    ratio = np.where(need > step, step / np.maximum(need, 1e-300), 1.0)
    scale = float(np.min(ratio))
    v_next = v + scale * dv
    low = (q_limits[0] - q) / period
    high = np.maximum((q_limits[1] - q) / period, low)
    v_next = np.clip(v_next, low, high)
    limited = scale < 1.0 or bool(np.any(np.abs(v_wanted) > max_speed))
    return q + v_next * period, v_next, limited
