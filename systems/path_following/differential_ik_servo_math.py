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
"""

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.linalg import _umath_linalg
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RigidBody

# Share of the acceleration limits the error feedback may plan with: the rest is kept for
# the target's own turns and speed changes, which reach the joints through the error.
FEEDBACK_ACCELERATION_SHARE = 0.5
# The joint-centring velocity at a joint's limit, as a share of its speed limit.
CENTRING_SPEED_SHARE = 0.3
# The damping away from singularities (a regularisation only).
MIN_DAMPING = 1e-3
# _SELECT: on a few floats, a conditional expression picks the operand min(a, b) or
# max(a, b) would (`b if b < a else a`, `b if b > a else a`) at a fraction of the cost: the
# builtins parse keyword arguments on every call, which costs more than a joint's arithmetic.


@dataclass(frozen=True)
class JointLimits:
    """Per joint: position range (rad), speed (rad/s) and acceleration (rad/s^2) limits.
    The lists below are derived once: ServoStep and StoppingPositions run at the servo
    rate on n joints, where numpy's per-call overhead exceeds its work, so they compute in
    Python floats (the same IEEE operations as numpy's elementwise ones, so the same values).
    """

    lower: np.ndarray
    upper: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    lower_list: list[float] = field(init=False, repr=False)
    upper_list: list[float] = field(init=False, repr=False)
    speed_list: list[float] = field(init=False, repr=False)
    acceleration_list: list[float] = field(init=False, repr=False)
    # 2 x acceleration (rad/s^2; doubling is exact, so products with it are unchanged).
    twice_acceleration_list: list[float] = field(init=False, repr=False)
    feedback_acceleration_list: list[float] = field(init=False, repr=False)
    # CentringVelocity's constants: the middle of each range (rad), half its width (rad),
    # the centring speed at a limit (rad/s).
    middle_list: list[float] = field(init=False, repr=False)
    half_range_list: list[float] = field(init=False, repr=False)
    centring_speed_list: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lower, upper = np.asarray(self.lower, float), np.asarray(self.upper, float)
        speed, acceleration = np.asarray(self.speed, float), np.asarray(self.acceleration, float)
        derived = {
            "lower_list": lower,
            "upper_list": upper,
            "speed_list": speed,
            "acceleration_list": acceleration,
            "twice_acceleration_list": 2 * acceleration,
            "feedback_acceleration_list": FEEDBACK_ACCELERATION_SHARE * acceleration,
            "middle_list": 0.5 * (lower + upper),
            "half_range_list": np.maximum(0.5 * (upper - lower), 1e-9),
            "centring_speed_list": CENTRING_SPEED_SHARE * speed,
        }
        for name, value in derived.items():
            object.__setattr__(self, name, value.tolist())


def PoseError(X_current: RigidTransform, X_desired: RigidTransform) -> np.ndarray:
    """[rotation vector; translation] (rad, m; in W) taking X_current to X_desired."""
    # R_desired R_current^-1 as the rotation of the composed transforms: the same product
    # in fewer pydrake calls.
    R_error = (X_desired @ X_current.inverse()).rotation()
    angle_axis = R_error.ToAngleAxis()
    w = angle_axis.axis() * angle_axis.angle()
    return np.concatenate([w, X_desired.translation() - X_current.translation()])


def SymmetricEigen(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.linalg.eigh(M) of a symmetric matrix M: (eigenvalues ascending, eigenvectors as
    columns), bit for bit, from eigh's own gufunc (LAPACK dsyevd on the lower triangle)
    called directly: eigh's checks and floating-point error context cost as much as
    decomposing a 6 x 6 matrix. numpy is pinned in pyproject.toml;
    tests/test_differential_ik_servo.py compares the two."""
    e, V = _umath_linalg.eigh_lo(M, signature="d->dd")
    if math.isnan(e[0]):  # the gufunc's NaNs where eigh raises
        raise np.linalg.LinAlgError("Eigenvalues did not converge")
    return e, V


def CentringVelocity(q: list[float], limits: JointLimits) -> list[float]:
    """Joint velocities (rad/s) toward the middle of each joint's range (q: rad): 0 there,
    CENTRING_SPEED_SHARE of the speed limit at a limit, cubic in between."""
    velocities = []
    for qi, middle, half_range, speed in zip(
        q, limits.middle_list, limits.half_range_list, limits.centring_speed_list, strict=True
    ):
        x = (middle - qi) / half_range
        x = -1.0 if x < -1.0 else 1.0 if x > 1.0 else x  # clipped to [-1, 1] (_SELECT)
        velocities.append(speed * x**3)
    return velocities


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
    changed v_next."""
    n = J.shape[1]
    # J, the error (and the twist) as one 6 x (n + 1 or 2) matrix, expressed in T (its two
    # 3-row halves rotated in one stacked product, each the same BLAS product as alone) and
    # weighted by rows; its normal equations in one product.
    columns = (J, error[:, None]) if twist is None else (J, error[:, None], twist[:, None])
    m = n + len(columns) - 1
    A = R_WT.T @ np.concatenate(columns, axis=1).reshape(2, 3, m)
    A = A.reshape(6, m)
    A *= weights[:, None]
    normal = A[:, :n].T @ A
    # J_T' J_T = V diag(e) V': sigma_min^2 of J_T is e[0], and the damped solve is diagonal.
    e, V = SymmetricEigen(normal[:, :n])
    lam2 = max(damping**2 - max(float(e[0]), 0.0), MIN_DAMPING**2)
    q_, v_ = q.tolist(), v.tolist()
    rhs = np.empty((n, m - n + 1))
    rhs[:, 0] = [lam2 * c for c in CentringVelocity(q_, limits)]
    rhs[:, 1:] = normal[:, n:]
    v_c, dq, *feedforward = (V @ ((V.T @ rhs) / (e + lam2)[:, None])).T.tolist()
    # The rest joint by joint in Python floats (JointLimits), in list comprehensions (the
    # cheapest loops in CPython).
    reach = max([abs(d) / a for d, a in zip(dq, limits.feedback_acceleration_list, strict=True)])
    scale = min(gain, math.sqrt(2.0 / reach)) if reach > 0 else gain
    v_wanted = [c + d * scale for c, d in zip(v_c, dq, strict=True)]
    if feedforward:
        v_wanted = [w + f for w, f in zip(v_wanted, feedforward[0], strict=True)]
    speed_ratio = min(
        [
            s / (1e-300 if abs(w) < 1e-300 else abs(w))  # s / max(|w|, 1e-300) (_SELECT)
            for s, w in zip(limits.speed_list, v_wanted, strict=True)
        ]
    )
    if speed_ratio < 1.0:
        v_wanted = [w * speed_ratio for w in v_wanted]
    excess = max(
        [
            abs(w - x) / (a * period)
            for w, x, a in zip(v_wanted, v_, limits.acceleration_list, strict=True)
        ]
    )
    # v + (v_wanted - v) scaled into the acceleration limits, then braking: at most the speed
    # from which the joint stops at its limit, and never past it (min and max as in _SELECT).
    q_next, v_next = [], []
    for qi, vi, wi, a2, lower, upper in zip(
        q_,
        v_,
        v_wanted,
        limits.twice_acceleration_list,
        limits.lower_list,
        limits.upper_list,
        strict=True,
    ):
        vi = vi + (wi - vi) / excess if excess > 1.0 else vi + (wi - vi)
        to_upper, to_lower = upper - qi, qi - lower
        high = math.sqrt(a2 * (0.0 if to_upper < 0.0 else to_upper))
        if to_upper / period < high:
            high = to_upper / period
        low = -math.sqrt(a2 * (0.0 if to_lower < 0.0 else to_lower))
        if -to_lower / period > low:
            low = -to_lower / period
        if low > high:
            high = low
        if low > vi:
            vi = low
        if high < vi:
            vi = high
        v_next.append(vi)
        q_next.append(qi + vi * period)
    limited = excess > 1.0 or speed_ratio < 1.0
    return np.array(q_next), np.array(v_next), limited


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
