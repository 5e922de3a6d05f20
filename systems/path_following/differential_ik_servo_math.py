"""Mathematics of the DifferentialIkServo: one period of resolved-rate control within
joint limits (rad, rad/s, rad/s^2; frames: world W, the controlled frame T).

With W = diag(weights) on the rows of J expressed in T (roll about x_T, pitch, yaw, then
x, y, z) and the damped weighted pseudo-inverse
    J# V = argmin |W (J v - V)|^2 + lambda^2 |v - v_centre|^2,
    lambda^2 = damping^2 (1 - (sigma_min / damping)^2) when the smallest singular value
    sigma_min of W J is below `damping`, else MIN_DAMPING^2
(the damping grows only near a singularity, where it trades the least weighted motion,
the tool's orientation, for bounded joint speeds; elsewhere the task is met exactly),
one period is
    v_ff  = J# V_target            the target's own velocity, fed forward, so that a
                                   steadily moving target leaves no growing lag
    dq    = J# error               the joints' displacement that closes the pose error
    v_fb  = dq min(gain, sqrt(2 a_fb / max_i |dq_i| / a_i))
    v_wanted = (v_ff + v_fb), scaled down as a whole into the speed limits
    v_next = v + s (v_wanted - v), s in [0, 1] the largest that keeps every joint within
             v +- acceleration x period
    q_next = q + v_next period, v_next braked so that every joint can stop before its
             position limit.

v_centre pulls each joint toward the middle of its range (stronger near the limits); the
damping term makes it act only where the task leaves freedom (near a singularity), so the
task itself is unchanged. The weights of the rotation rows are lengths (m/rad): a rotation
error of 1 rad counts as much as a position error of that length, so the tool's position,
which the tracking needs, comes first when the two conflict.

The feedback is proportional (gain, 1/s) for small errors and follows the braking curve
sqrt(2 a_fb |dq|) for large ones, a_fb a share of the acceleration limits: a joint
commanded faster than it can brake before the error closes overshoots, and with the
acceleration limits binding the overshoot grows into a swinging limit cycle. Scaling the
whole velocity (and its change), not clipping joint by joint, keeps the frame's motion
along the commanded direction: a clipped joint bends it, and in a fast turn the bent
motion fed back into a growing error.

Drake's DoDifferentialInverseKinematics keeps J v_next parallel to V and assumes the
joints start at rest; with acceleration limits that has no solution whenever the error
turns faster than the joints may, and the arm stalls. The damped least squares always has
one.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

# Share of the acceleration limits the error feedback may plan with: the rest is kept for
# the changes of the feed-forward (the target's turns and speed changes).
FEEDBACK_ACCELERATION_SHARE = 0.5
# The joint-centring velocity at a joint's limit, as a share of its speed limit.
CENTRING_SPEED_SHARE = 0.3
# The damping away from singularities (a regularisation only).
MIN_DAMPING = 1e-3


@dataclass(frozen=True)
class JointLimits:
    """Per joint: position range (rad), speed (rad/s) and acceleration (rad/s^2) limits."""

    lower: np.ndarray
    upper: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray


def PoseError(X_current: RigidTransform, X_desired: RigidTransform) -> np.ndarray:
    """[rotation vector; translation] (rad, m; in W) taking X_current to X_desired."""
    R_error = X_desired.rotation().multiply(X_current.rotation().inverse())
    angle_axis = R_error.ToAngleAxis()
    w = angle_axis.axis() * angle_axis.angle()
    return np.concatenate([w, X_desired.translation() - X_current.translation()])


def CentringVelocity(q: np.ndarray, limits: JointLimits) -> np.ndarray:
    """Joint velocities (rad/s) toward the middle of each joint's range: 0 there,
    CENTRING_SPEED_SHARE of the speed limit at a limit, cubic in between."""
    middle = 0.5 * (limits.lower + limits.upper)
    half = np.maximum(0.5 * (limits.upper - limits.lower), 1e-9)
    x = np.clip((middle - q) / half, -1.0, 1.0)
    return CENTRING_SPEED_SHARE * limits.speed * x**3


def ServoStep(
    J: np.ndarray,
    V_target: np.ndarray,
    error: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    period: float,
    limits: JointLimits,
    R_WT: np.ndarray,
    weights: np.ndarray,
    damping: float,
    gain: float,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """(q_next, v_next, limited): one period (module docstring). J: the 6 x n spatial
    velocity Jacobian of T in W at q; V_target: the target's spatial velocity and error:
    the pose error of T (both [w; v] in W, PoseError's order); R_WT: T's orientation
    (3 x 3); limited: whether a speed or acceleration limit changed v_next."""
    n = J.shape[1]
    w = np.asarray(weights, float)[:, None]
    R_TW = R_WT.T
    J_T = np.vstack([R_TW @ J[:3], R_TW @ J[3:]]) * w
    # The feed-forward and the error as the two columns of one right-hand side.
    E = np.column_stack([V_target, error])
    E_T = np.vstack([R_TW @ E[:3], R_TW @ E[3:]]) * w
    JtJ = J_T.T @ J_T
    # sigma_min^2 of J_T: the smallest eigenvalue of J_T' J_T.
    sigma_min2 = max(float(np.linalg.eigvalsh(JtJ)[0]), 0.0)
    lam2 = max(damping**2 - sigma_min2, MIN_DAMPING**2)
    rhs = J_T.T @ E_T
    rhs[:, 0] += lam2 * CentringVelocity(q, limits)
    solution = np.linalg.solve(JtJ + lam2 * np.eye(n), rhs)
    v_ff, dq = solution[:, 0], solution[:, 1]
    a_fb = FEEDBACK_ACCELERATION_SHARE * limits.acceleration
    reach = float((np.abs(dq) / a_fb).max())
    v_fb = dq * (min(gain, np.sqrt(2.0 / reach)) if reach > 0 else gain)
    v_wanted = v_ff + v_fb
    speed_ratio = float((limits.speed / np.maximum(np.abs(v_wanted), 1e-300)).min())
    v_wanted = v_wanted * min(1.0, speed_ratio)
    dv = v_wanted - v
    step = limits.acceleration * period
    excess = np.abs(dv) / step
    scale = 1.0 / max(1.0, float(excess.max()))
    v_next = v + scale * dv
    # Braking: at most the speed from which the joint stops at its limit, and never past it.
    a = limits.acceleration
    high = np.minimum(
        np.sqrt(2 * a * np.maximum(limits.upper - q, 0.0)), (limits.upper - q) / period
    )
    low = np.maximum(
        -np.sqrt(2 * a * np.maximum(q - limits.lower, 0.0)), (limits.lower - q) / period
    )
    v_next = np.minimum(np.maximum(v_next, low), np.maximum(high, low))
    limited = scale < 1.0 or speed_ratio < 1.0
    return q + v_next * period, v_next, limited


def StoppingPositions(q: np.ndarray, v: np.ndarray, limits: JointLimits) -> np.ndarray:
    """Where each joint comes to rest (rad) braking from v at its acceleration limit."""
    return q + v * np.abs(v) / (2 * limits.acceleration)


def BrakeStep(
    q: np.ndarray, v: np.ndarray, period: float, limits: JointLimits
) -> tuple[np.ndarray, np.ndarray]:
    """(q_next, v_next): one period of braking every joint at its acceleration limit."""
    step = limits.acceleration * period
    v_next = v - np.clip(v, -step, step)
    return q + v_next * period, v_next
