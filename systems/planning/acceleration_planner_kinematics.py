"""Kinematics of the acceleration-level planner: p = k(q), Jacobians, Jdot qd, the tracking
error (6) and the blended target (19), and the singularity-robust inverse.

Two representations of the TCP orientation, one per planner mode:
- the paper's (Pająk): Z-Y-X Euler angles phi = [roll, pitch, yaw] (R = Rz(yaw) Ry(pitch)
  Rx(roll)) with the analytic Jacobian J = diag(I, B^-1(phi)) J_g, singular at pitch +-90 deg;
- the robust mode's: the rotation matrix itself, the error a rotation vector and its rate
  the angular velocity, so J is the geometric Jacobian J_g, with no representation
  singularity.

Frames: tool frame T (the TCP) measured in the arm's base frame B; J_g, Jdot qd from the
MultibodyPlant (any 6-DoF arm). Units: m, rad, s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.linalg import _umath_linalg
from pydrake.math import RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable, ModelInstanceIndex

from guidedarm.systems.config_checks import POSITIVE, CheckArgument
from guidedarm.systems.errors import ConfigurationError, RunFailedError
from guidedarm.systems.plant_frames import CheckFrame, CheckModelInstance, CheckPlant


class PlanningError(RunFailedError):
    """The planner cannot continue (singular arm in the paper's mode, infeasible scaling)."""


def WrapAngle(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to [-pi, pi) (rad)."""
    return (np.asarray(angle, float) + np.pi) % (2.0 * np.pi) - np.pi


def EulerRateMatrix(rpy: np.ndarray) -> np.ndarray:
    """B(phi) with omega = B(phi) [roll', pitch', yaw']' for R = Rz(yaw) Ry(pitch) Rx(roll).

    The seed prints B with its columns ordered (yaw', pitch', roll'); here they follow the
    order of phi = [roll, pitch, yaw] so that J = diag(I, B^-1) J_g matches e = k(q) - p_f.
    """
    sy, cy = math.sin(rpy[1]), math.cos(rpy[1])
    sz, cz = math.sin(rpy[2]), math.cos(rpy[2])
    return np.array([[cy * cz, -sz, 0.0], [cy * sz, cz, 0.0], [-sy, 0.0, 1.0]])


def EulerRateMatrixInverse(rpy: np.ndarray) -> np.ndarray:
    """B(phi)^-1 in closed form (singular at pitch = +-pi/2)."""
    sy, cy = math.sin(rpy[1]), math.cos(rpy[1])
    sz, cz = math.sin(rpy[2]), math.cos(rpy[2])
    return np.array([[cz / cy, sz / cy, 0.0], [-sz, cz, 0.0], [cz * sy / cy, sz * sy / cy, 1.0]])


def EulerRateMatrixDotTimesRate(rpy: np.ndarray, rpy_dot: np.ndarray) -> np.ndarray:
    """dB/dt (phi, phi') @ phi' (rad/s^2), the term that turns alpha into phi''."""
    droll, dpitch, dyaw = rpy_dot
    sy, cy = math.sin(rpy[1]), math.cos(rpy[1])
    sz, cz = math.sin(rpy[2]), math.cos(rpy[2])
    return np.array(
        [
            (-sy * cz * dpitch - cy * sz * dyaw) * droll - cz * dyaw * dpitch,
            (-sy * sz * dpitch + cy * cz * dyaw) * droll - sz * dyaw * dpitch,
            -cy * dpitch * droll,
        ]
    )


def RotationVector(R: np.ndarray) -> np.ndarray:
    """log(R) as a rotation vector theta n (rad), theta in [0, pi]; accurate near 0 and pi."""
    return np.array(_RotationVector(R.tolist()))


def _RotationVector(R: list[list[float]]) -> list[float]:
    """RotationVector of R given as rows of floats (scalar arithmetic: a 3 x 3 costs less
    than NumPy's per-call overhead)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R
    w0, w1, w2 = r21 - r12, r02 - r20, r10 - r01
    cos_theta = 0.5 * (r00 + r11 + r22 - 1.0)
    # clipped to [-1, 1] by comparisons (cheaper than builtin min / max calls)
    cos_theta = 1.0 if cos_theta > 1.0 else (-1.0 if cos_theta < -1.0 else cos_theta)
    sin_theta = 0.5 * math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    theta = math.atan2(sin_theta, cos_theta)
    if theta < 1e-8:
        return [0.5 * w0, 0.5 * w1, 0.5 * w2]
    if theta < math.pi - 1e-4:
        f = theta / (2.0 * sin_theta)
        return [f * w0, f * w1, f * w2]
    # Near pi the skew part vanishes: the axis is the dominant column of (R + I) / 2 = n n^T.
    nn = 0.5 * (np.array(R) + np.eye(3))
    k = int(np.argmax(np.diag(nn)))
    axis = nn[:, k] / math.sqrt(max(nn[k, k], 1e-300))
    if axis[0] * w0 + axis[1] * w1 + axis[2] * w2 < 0:
        axis = -axis
    return (theta * axis).tolist()


def RotationFromVector(v: np.ndarray) -> np.ndarray:
    """exp([v]x) by Rodrigues' formula: the rotation of angle |v| (rad) about v."""
    theta = math.sqrt(v.dot(v))
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    if theta < 1e-8:
        return _IDENTITY + K
    return _IDENTITY + (math.sin(theta) / theta) * K + ((1 - math.cos(theta)) / theta**2) * K.dot(K)


_IDENTITY = np.eye(3)
_IDENTITY.flags.writeable = False


def RotationError(R: np.ndarray, R_target: np.ndarray) -> np.ndarray:
    """Orientation error of R with respect to R_target, both in B: the rotation vector of
    R R_target^T (rad, expressed in B). Along the geodesic from R_target about a fixed axis
    its rate is the angular velocity omega, so e' = J_g qd for the rotational rows."""
    return RotationVector(R @ R_target.T)


def DampingFactor(sigma: float, threshold: float, max_damping: float) -> float:
    """lambda^2 of the damped inverse: 0 for sigma >= threshold, rising smoothly to
    max_damping^2 as the smallest singular value sigma falls to 0 (Nakamura-Hanafusa,
    Chiaverini): lambda^2 = max_damping^2 (1 - (sigma / threshold)^2)."""
    if sigma >= threshold:
        return 0.0
    return max_damping**2 * (1.0 - (sigma / threshold) ** 2)


def InverseAndConditioning(kin: TcpKinematics, floor: float) -> tuple[np.ndarray | None, float]:
    """(J^-1, s) with s >= floor a lower bound of J's smallest singular value,
    1 / ||J^-1||_F, when that bound already reaches floor; else (None, the smallest singular
    value itself, from an SVD). One 6 x 6 inverse per step instead of an SVD and a solve
    where the arm is well conditioned, i.e. wherever no damping or blending depends on s."""
    # The LAPACK gufunc behind np.linalg.inv, without its checks and error-state context,
    # which cost three times the 6 x 6 inverse; a singular J gives NaNs (and NumPy's
    # "invalid value" warning), which fail the bound test below. J is float64, the
    # gufunc's default loop: no signature keyword to parse.
    inverse = _umath_linalg.inv(kin.J)
    flat = inverse.reshape(-1)
    norm2 = float(flat.dot(flat))
    if norm2 <= 1.0 / (floor * floor):  # False for NaN as well
        return inverse, 1.0 / math.sqrt(norm2)
    return None, kin.min_singular_value


def DampedSolve(
    J: np.ndarray, rhs: np.ndarray, damping: float, inverse: np.ndarray | None = None
) -> np.ndarray:
    """J^# rhs with J^# = J^T (J J^T + damping I)^-1, the singularity-robust inverse;
    exactly J^-1 rhs for damping = 0 (with J^-1 = `inverse` when given)."""
    if damping == 0.0:
        return inverse.dot(rhs) if inverse is not None else np.linalg.solve(J, rhs)
    return J.T @ np.linalg.solve(J @ J.T + damping * np.eye(J.shape[0]), rhs)


@dataclass(slots=True)
class TcpKinematics:
    """The TCP at (q, qd): position x (m) and rotation R of T in B, Euler angles rpy (rad),
    the Jacobian J (6 x 6, rows [translational; rotational]: analytic with Euler rates in
    the paper's mode, geometric with omega in the robust mode), Jdot qd (m/s^2, rad/s^2) in
    the same rows, and sigma, the smallest singular value of J_g (in the robust mode
    computed from J, J_g's rows swapped, on first use). rpy is only evaluated for the
    paper's mode (p computes it otherwise). x is a list of floats: the robust step's
    position arithmetic on three floats costs less than NumPy's calls."""

    x: list[float]
    R: np.ndarray
    rpy: np.ndarray | None
    J: np.ndarray
    Jdot_qdot: np.ndarray
    sigma: float | None = None

    @property
    def min_singular_value(self) -> float:
        if self.sigma is None:
            self.sigma = float(np.linalg.svd(self.J, compute_uv=False)[-1])
        return self.sigma

    @property
    def p(self) -> np.ndarray:
        """p = [x; roll, pitch, yaw] as in the paper."""
        rpy = self.rpy if self.rpy is not None else RollPitchYaw(RotationMatrix(self.R)).vector()
        return np.concatenate([self.x, rpy])


class ArmKinematics:
    """k(q), J(q) and Jdot(q, qd) qd of tool frame T in base frame B from a MultibodyPlant.

    The plant may hold other models (tools, scene); only the joints of `instance` move.
    Evaluate(q, qd, analytic=True) is the paper's: it raises PlanningError at a near-singular
    configuration, the smallest singular value of J_g below `min_singular_value` or |pitch|
    within `min_singular_value` (rad) of 90 deg, where the Euler angles themselves are
    singular. Evaluate(q, qd, analytic=False) gives the geometric Jacobian and never raises.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        instance: ModelInstanceIndex,
        base_frame: Frame,
        tool_frame: Frame,
        min_singular_value: float = 0.01,
    ) -> None:
        CheckPlant("plant", plant)
        CheckModelInstance("instance", instance, plant)
        CheckFrame("base_frame", base_frame, plant)
        CheckFrame("tool_frame", tool_frame, plant)
        CheckArgument("min_singular_value", min_singular_value, POSITIVE)
        if plant.num_velocities(instance) != 6 or plant.num_positions(instance) != 6:
            raise ConfigurationError(
                f"the planner needs a 6-DoF arm; {plant.GetModelInstanceName(instance)} has "
                f"{plant.num_velocities(instance)} joints"
            )
        self.plant = plant
        self.instance = instance
        self.base_frame = base_frame
        self.tool_frame = tool_frame
        self.min_singular_value = min_singular_value
        self._context = plant.CreateDefaultContext()
        # the arm is the plant's whole state: set it without the model-instance mapping
        self._whole_state = plant.num_multibody_states() == 12
        velocity_start = np.arange(plant.num_velocities())
        columns = plant.GetVelocitiesFromArray(instance, velocity_start).astype(int)
        # the arm's columns of J_g (None: all of them, in order)
        self._columns = None if np.array_equal(columns, np.arange(6)) else columns
        # Drake's spatial rows are [rotational; translational]; the planner's [x; rotation]
        self._rows = np.array([3, 4, 5, 0, 1, 2])
        self._origin = np.zeros(3)
        self._state = np.empty(12)
        self._wrt = JacobianWrtVariable.kV  # a pybind enum's attribute lookup costs a call

    def Evaluate(self, q: np.ndarray, qd: np.ndarray, analytic: bool = True) -> TcpKinematics:
        """Kinematics at joint positions q (rad) and velocities qd (rad/s): one update of
        the plant's context, then the pose, J_g and the bias acceleration from its caches."""
        plant, context, x = self.plant, self._context, self._state
        # two slice copies into a preallocated [q; qd] cost less than np.concatenate
        x[:6] = q
        x[6:] = qd
        if self._whole_state:
            plant.SetPositionsAndVelocities(context, x)
        else:
            plant.SetPositionsAndVelocities(context, self.instance, x)
        X_BT = plant.CalcRelativeTransform(context, self.base_frame, self.tool_frame)
        pose = X_BT.GetAsMatrix34()
        # T's origin, measured and expressed in B, with respect to v; rows [x; rotation].
        Jg = plant.CalcJacobianSpatialVelocity(
            context, self._wrt, self.tool_frame, self._origin, self.base_frame, self.base_frame,
        )  # fmt: skip
        if self._columns is not None:
            Jg = Jg.take(self._columns, axis=1)
        # take: a copy in the planner's row order, several times cheaper than fancy indexing
        J = Jg.take(self._rows, axis=0)
        bias = plant.CalcBiasSpatialAcceleration(
            context, self._wrt, self.tool_frame, self._origin, self.base_frame, self.base_frame,
        )  # fmt: skip
        Jdot_qdot = bias.get_coeffs().take(self._rows)
        if not analytic:
            return TcpKinematics(pose[:, 3].tolist(), pose[:, :3], None, J, Jdot_qdot)
        rpy = RollPitchYaw(X_BT.rotation()).vector()
        sigma = float(np.linalg.svd(J, compute_uv=False)[-1])
        self._CheckSingularity(sigma, rpy, q)
        B_inv = EulerRateMatrixInverse(rpy)
        J[3:] = B_inv @ J[3:]
        rpy_dot = J[3:] @ qd
        Jdot_qdot[3:] = B_inv @ (Jdot_qdot[3:] - EulerRateMatrixDotTimesRate(rpy, rpy_dot))
        return TcpKinematics(pose[:, 3].tolist(), pose[:, :3], rpy, J, Jdot_qdot, sigma)

    def Position(self, q: np.ndarray) -> np.ndarray:
        """p = k(q): TCP position (m) and Z-Y-X Euler angles (rad) in the base frame."""
        self.plant.SetPositions(self._context, self.instance, q)
        X_BT = self.plant.CalcRelativeTransform(self._context, self.base_frame, self.tool_frame)
        return np.concatenate([X_BT.translation(), RollPitchYaw(X_BT.rotation()).vector()])

    def JointLimits(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's joint position limits (rad), at most +-pi (a turn covers every angle)."""
        lower, upper = self.PositionLimits()
        return np.maximum(lower, -np.pi), np.minimum(upper, np.pi)

    def PositionLimits(self) -> tuple[np.ndarray, np.ndarray]:
        """The arm's joint position limits (rad) as the plant has them (+-inf if none)."""
        plant, instance = self.plant, self.instance
        lower = plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits())
        upper = plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits())
        return lower, upper

    def MinSingularValue(self, q: np.ndarray) -> float:
        """Smallest singular value of the geometric Jacobian J_g at q (m or rad per rad)."""
        return self.Evaluate(q, np.zeros(6), analytic=False).min_singular_value

    def _CheckSingularity(self, sigma: float, rpy: np.ndarray, q: np.ndarray) -> None:
        if sigma < self.min_singular_value:
            raise PlanningError(
                f"near-singular arm configuration q={np.round(q, 4).tolist()} rad: smallest "
                f"singular value of the Jacobian {sigma:.2e} < {self.min_singular_value}"
            )
        if np.pi / 2 - abs(rpy[1]) < self.min_singular_value:
            raise PlanningError(
                f"TCP pitch {rpy[1]:.4f} rad is at the Z-Y-X Euler-angle singularity (+-pi/2)"
            )


def TrackingError(p: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Eq. (6): e = k(q) - p_target (m, rad) with the Euler-angle part wrapped (paper's mode)."""
    e = p - target
    e[3:] = WrapAngle(e[3:])
    return e


def PoseError(kin: TcpKinematics, x_target: Sequence[float], R_target: np.ndarray) -> np.ndarray:
    """The robust mode's e: [x - x_target; rotation vector of R R_target^T] (m, rad, in B)."""
    x = kin.x
    return np.array(
        [x[0] - x_target[0], x[1] - x_target[1], x[2] - x_target[2]]
        + _RotationVector(kin.R.dot(R_target.T).tolist())
    )


def BlendedTarget(p_i: np.ndarray, p_next: np.ndarray, sigma: float) -> np.ndarray:
    """Eq. (19): sigma p_{i+1} + (1 - sigma) p_i, the Euler-angle difference wrapped."""
    delta = p_next - p_i
    delta[3:] = WrapAngle(delta[3:])
    return p_i + sigma * delta


def BlendedPose(
    pose_i: tuple[Sequence[float], np.ndarray],
    pose_next: tuple[Sequence[float], np.ndarray],
    sigma: float,
    rotation: np.ndarray | None = None,
) -> tuple[list[float], np.ndarray]:
    """Eq. (19) for (x, R) poses (x: three floats, m): the position interpolated
    linearly, the rotation along
    the geodesic R_i exp(sigma log(R_i^T R_{i+1})) (robust mode; `rotation`: log(R_i^T
    R_{i+1}) if already known, a constant of the waypoint pair)."""
    (x_i, R_i), (x_next, R_next) = pose_i, pose_next
    if rotation is None:
        rotation = RotationVector(R_i.T @ R_next)
    x = [a + sigma * (b - a) for a, b in zip(x_i, x_next, strict=True)]
    return x, R_i.dot(RotationFromVector(sigma * rotation))
