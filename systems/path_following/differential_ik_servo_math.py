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
    v_c   = the damping's share of v_centre (below)
    dq    = J# error               the joints' displacement that closes the pose error
    v_fb  = dq min(gain, sqrt(2 a_fb / max_i |dq_i| / a_i))
    v_wanted = (v_c + v_fb), scaled down as a whole into the speed limits
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

ServoStep and PoseError run in a compiled kernel (csrc/servo_step.c, built by the install):
in Python, a period cost about 70 us, nearly all of it the overhead of some 40 numpy and
float operations on six joints. tests/differential_ik_servo_reference.py keeps the numpy
implementation they are tested against (to 1e-12 on random inputs).
"""

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RigidBody

from guidedarm.systems.path_following import _servo_step

# The constants below are also those of the compiled kernel (csrc/servo_step.c).
# Share of the acceleration limits the error feedback may plan with: the rest is kept for
# the target's own turns and speed changes, which reach the joints through the error.
FEEDBACK_ACCELERATION_SHARE = 0.5
# The joint-centring velocity at a joint's limit, as a share of its speed limit.
CENTRING_SPEED_SHARE = 0.3
# The damping away from singularities (a regularisation only).
MIN_DAMPING = 1e-3
_NO_TWIST = np.empty(0)


@dataclass(frozen=True)
class JointLimits:
    """Per joint: position range (rad), speed (rad/s) and acceleration (rad/s^2) limits,
    stored as contiguous float64 arrays (the compiled kernel reads them as they are)."""

    lower: np.ndarray
    upper: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    # 2 x acceleration as floats, for StoppingPositions at the servo rate on six joints,
    # where numpy's per-call overhead exceeds its work (doubling is exact: the same values).
    twice_acceleration_list: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "speed", "acceleration"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), float))
        object.__setattr__(self, "twice_acceleration_list", (2 * self.acceleration).tolist())


def PoseError(X_current: RigidTransform, X_desired: RigidTransform) -> np.ndarray:
    """[rotation vector; translation] (rad, m; in W) taking X_current to X_desired."""
    return PoseErrorOfRows(Rows(X_current), Rows(X_desired))


def PoseErrorOfRows(M_current: np.ndarray, M_desired: np.ndarray) -> np.ndarray:
    """PoseError of two poses given as Rows gives them."""
    error = np.empty(6)
    _servo_step.PoseError(M_current, M_desired, error)
    return error


def Rows(X: RigidTransform) -> np.ndarray:
    """X as the kernel reads a pose: [R | p], 3 x 4, row-major (pydrake's matrices are
    column-major)."""
    return np.ascontiguousarray(X.GetAsMatrix34())


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
    """(q_next, v_next, limited): one period (module docstring). J: the 6 x n spatial
    velocity Jacobian of T in W at q; error: the pose error of T ([w; v] in W, PoseError's
    order); R_WT: T's orientation (3 x 3); twist: the target's own velocity ([w; v] in W,
    rad/s and m/s), fed forward through the same least squares (v_ff = J# twist, added to
    the feedback); None: feedback only; limited: whether a speed or acceleration limit
    changed v_next. Computed by the compiled kernel (csrc/servo_step.c)."""
    q_next, v_next = np.empty(len(q)), np.empty(len(q))
    limited = _servo_step.ServoStep(
        np.ascontiguousarray(J, float),
        np.ascontiguousarray(error, float),
        _NO_TWIST if twist is None else np.ascontiguousarray(twist, float),
        np.ascontiguousarray(q, float),
        np.ascontiguousarray(v, float),
        period,
        limits.lower,
        limits.upper,
        limits.speed,
        limits.acceleration,
        np.ascontiguousarray(R_WT, float),
        np.ascontiguousarray(weights, float),
        damping,
        gain,
        q_next,
        v_next,
    )
    return q_next, v_next, limited


def ServoPeriod(
    J: np.ndarray,
    M_WT: np.ndarray,
    M_WD: np.ndarray,
    previous: np.ndarray,
    feedforward: float,
    q: np.ndarray,
    v: np.ndarray,
    period: float,
    limits: JointLimits,
    weights: np.ndarray,
    damping: float,
    gain: float,
    q_next: np.ndarray,
    v_next: np.ndarray,
) -> tuple[bool, list[float]]:
    """One DifferentialIkServo period in one call of the kernel: ServoStep on the pose
    error PoseErrorOfRows(M_WT, M_WD) (T at M_WT, the target at M_WD, both as Rows gives
    them), R_WT from M_WT, and the twist PoseErrorOfRows(previous, M_WD) * feedforward
    (1/s; none when feedforward is 0 or previous, the last period's M_WD, is NaN); writes
    q_next and v_next (n, contiguous float64, e.g. the update's state) and returns
    (limited, StoppingPositions(q_next, v_next, limits)): the same values as those calls
    (tests/test_differential_ik_servo_kernel.py), without their per-call overhead at the
    servo rate."""
    return _servo_step.ServoPeriod(
        np.ascontiguousarray(J, float),
        M_WT,
        M_WD,
        previous,
        feedforward,
        q,
        v,
        period,
        limits.lower,
        limits.upper,
        limits.speed,
        limits.acceleration,
        weights,
        damping,
        gain,
        q_next,
        v_next,
    )


def ReachBound(plant: MultibodyPlant, bodies: list[RigidBody]) -> float:
    """R (m) such that no origin of `bodies` moves farther than R sum_j |dq_j| when the
    plant's joints change by dq: the longest chain of fixed distances from a moving body's
    origin through the joint origins to a body no joint moves. inf unless every joint
    is revolute (origin fixed in both bodies) or a weld."""
    joints = [plant.get_joint(j) for j in plant.GetJointIndices()]
    if any(j.type_name() not in ("revolute", "weld") for j in joints):
        return math.inf
    inboard = {j.child_body().index(): j for j in joints}

    def Chain(body: RigidBody, p_BP: np.ndarray) -> float:
        """Distance from point P (in body B) to the fixed base through the joints."""
        joint = inboard.get(body.index())
        if joint is None:
            return 0.0
        p_BJ = joint.frame_on_child().GetFixedPoseInBodyFrame().translation()
        p_PJ = joint.frame_on_parent().GetFixedPoseInBodyFrame().translation()
        return float(np.linalg.norm(p_BP - p_BJ)) + Chain(joint.parent_body(), p_PJ)

    return max(Chain(body, np.zeros(3)) for body in bodies)


def StoppingPositions(q: np.ndarray, v: np.ndarray, limits: JointLimits) -> list[float]:
    """Where each joint comes to rest (rad) braking from v (rad/s) at its acceleration
    limit."""
    return [
        qi + vi * abs(vi) / a2
        for qi, vi, a2 in zip(q.tolist(), v.tolist(), limits.twice_acceleration_list, strict=True)
    ]


def BrakeStep(
    q: np.ndarray, v: np.ndarray, period: float, limits: JointLimits
) -> tuple[np.ndarray, np.ndarray]:
    """(q_next, v_next): one period of braking every joint at its acceleration limit."""
    step = limits.acceleration * period
    v_next = v - np.clip(v, -step, step)
    return q + v_next * period, v_next
