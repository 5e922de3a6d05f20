"""Acceleration-level trajectory planning through TCP waypoints: the law.

Pająk, "Trajectory planning of an industrial 6-DOF manipulator with regards to joint velocity
and acceleration constraints" (the Pająk paper). The commanded joint acceleration follows
the error dynamics (9)

    e'' + Lambda_V e' + Lambda_P e = 0,    e = k(q) - p_target  (6),

solved for q'' (13), (16), (17):

    q'' = a + c b,   a = -J^-1 Jdot qd,   b = -J^-1 (Lambda_V J qd + Lambda_P e) + dq''_penalty,

with the interior velocity penalty (14)-(15), the acceleration scaling c(t) (cases (1)-(4),
rules (a)-(c), the return (18); systems/planning/acceleration_planner_limits.py) and the
blended target (19) that passes waypoints without stopping, or a stop at each.

Two modes (`PlannerConfig.robust`):
- robust = False, the paper's law exactly as published: Z-Y-X Euler angles and the analytic
  Jacobian (systems/planning/acceleration_planner_kinematics.py); a near-singular arm or an
  inadmissible case (c) stops the planner with a PlanningError.
- robust = True (default), beyond the paper: rotation-vector orientation error with the
  geometric Jacobian (no Euler singularity), a damped inverse J^# whose damping follows the
  smallest singular value, a speed governor that keeps a within `bias_margin` of the
  acceleration limits (so c = 0 stays admissible and case (c) cannot arise), step bounds
  that keep qd within its limits at every step, and a braking fallback should no admissible
  c exist all the same; c then restarts from 0 as at the smooth start.

Units: m, rad, s throughout; rows [x, y, z, roll, pitch, yaw] of the TCP T in base frame B.
systems/planning/acceleration_planner.py wraps the law in a LeafSystem.
"""

import copy
import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_config import PlannerConfig
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    ArmKinematics,
    BlendedPose,
    BlendedTarget,
    DampedSolve,
    DampingFactor,
    InverseAndConditioning,
    PlanningError,
    PoseError,
    TcpKinematics,
    TrackingError,
)
from guidedarm.systems.planning.acceleration_planner_limits import (
    AccelerationScaling,
    AdmissibleScaling,
    BrakingAcceleration,
    GovernorBraking,
    JerkLimited,
    ScalingReturn,
    StepBounds,
    VelocityPenalty,
)
from guidedarm.systems.planning.acceleration_planner_state import (
    PlannedTrajectory,
    PlannerState,
)


@dataclass
class PlannerTask:
    """A task given to a running planner: `waypoints` rows [x, y, z, roll, pitch, yaw] of
    the TCP T in the base frame B (m, rad, Z-Y-X Euler angles), the last one the final
    location. A `sequence` number different from the running task's restarts the law with
    these waypoints; a negative one means no task."""

    sequence: int = -1
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))


def AccelerationTerms(
    kin: TcpKinematics,
    qd: np.ndarray,
    e: np.ndarray,
    gain_p: float,
    gain_v: float,
    damping: float = 0.0,
    inverse: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (13) split as in (17): a = -J^-1 Jdot qd and b = -J^-1 (Lambda_V J qd +
    Lambda_P e) (rad/s^2), with J^-1 the damped inverse J^# when damping (lambda^2) > 0
    (`inverse`: J^-1 if already known)."""
    rhs = np.empty((6, 2))
    rhs[:, 0] = kin.Jdot_qdot
    rhs[:, 1] = gain_v * (kin.J @ qd) + gain_p * e
    solved = DampedSolve(kin.J, rhs, damping, inverse)
    return -solved[:, 0], -solved[:, 1]


def ApproachTerms(
    kin: TcpKinematics,
    qd: np.ndarray,
    e: np.ndarray,
    rates: tuple[float, float, float],
    inverse_braking: np.ndarray,
    damping: float = 0.0,
    inverse: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The robust mode's (a, b) with the braking approach: the error dynamics
    e'' = -(k + r) e' - (k r + r') e, i.e. e' tracks -r e at the rate k. (9) is this with
    constants r = r0 and k = k0, its roots (rates = (r0, k0, r_max), 1/s). Here
    r = sqrt(r0^2 + h), h = 2 / (d + 2 / (r_max^2 - r0^2)), grows as the joint
    displacement to go u = J^-1 e shrinks, d = ||u * inverse_braking||_4 (s^2;
    inverse_braking = 1 / (eta A) per joint, s^2/rad): a joint u_i from the target moves at
    most about sqrt(2 eta A_i u_i), the speed from which braking at eta A_i stops it there
    (the square-root law of time-optimal braking), r0 far away, r_max at the target; k
    rises with r in proportion (k = k0 r / r0), so the slower root is r, not k0. r' follows
    d' = grad d . qd (u' = qd to first order), so q'' stays continuous in the state."""
    rhs = np.empty((6, 3))
    rhs[:, 0] = kin.Jdot_qdot
    rhs[:, 1] = kin.J @ qd
    rhs[:, 2] = e
    solved = DampedSolve(kin.J, rhs, damping, inverse)
    r0, k0, r_max = rates
    u = solved[:, 2]
    x = np.abs(u) * inverse_braking
    x2 = x * x
    d = float(x2 @ x2) ** 0.25
    if d < 1e-12:
        r, r_dot = r_max, 0.0
    else:
        h = 2.0 / (d + 2.0 / (r_max * r_max - r0 * r0))
        r = math.sqrt(r0 * r0 + h)
        d_dot = float((x2 * x * np.sign(u) * inverse_braking) @ qd) / d**3
        r_dot = -0.25 * h * h / r * d_dot
    k = k0 * r / r0
    return -solved[:, 0], -(k + r) * solved[:, 1] - (k * r + r_dot) * u


class AccelerationPlanning:
    """One planner: kinematics, waypoints P = [p_1 .. p_w] (rows [x y z roll pitch yaw] in
    the base frame, m and rad), limits (None switches a constraint off) and parameters.

    Step(state) advances the commanded trajectory by one time step; the acceleration is
    held constant over the step, so q is piecewise quadratic and qd piecewise linear, and
    the limits checked at the samples hold over the whole step.
    """

    def __init__(
        self,
        kinematics: ArmKinematics,
        waypoints: np.ndarray,
        parameters: PlannerConfig,
        velocity_limits: tuple[np.ndarray, np.ndarray] | None = None,
        acceleration_limits: tuple[np.ndarray, np.ndarray] | None = None,
        joint_waypoints: np.ndarray | None = None,
    ) -> None:
        parameters.Validate()
        self.kinematics = kinematics
        self.parameters = parameters
        self._SetWaypoints(waypoints, joint_waypoints)
        self.penalty = (
            VelocityPenalty(
                *velocity_limits, parameters.velocity_threshold, parameters.penalty_strength
            )
            if velocity_limits is not None
            else None
        )
        self.scaling = (
            AccelerationScaling(*acceleration_limits) if acceleration_limits is not None else None
        )
        self.inverse_braking = None
        if parameters.robust and parameters.approach_acceleration > 0 and self.scaling:
            braking = np.minimum(self.scaling.upper, -self.scaling.lower)
            self.inverse_braking = 1.0 / (parameters.approach_acceleration * braking)
            r0 = parameters.SlowRoot()
            self.approach_rates = (r0, parameters.gain_v - r0, parameters.approach_rate)

    def _SetWaypoints(self, waypoints: np.ndarray, joint_waypoints: np.ndarray | None) -> None:
        waypoints = np.atleast_2d(np.asarray(waypoints, float))
        if waypoints.ndim != 2 or waypoints.shape[1] != 6 or waypoints.shape[0] == 0:
            raise ConfigurationError(
                f"waypoints must be rows of [x, y, z, roll, pitch, yaw], got {waypoints.shape}"
            )
        if not np.all(np.isfinite(waypoints)):
            raise ConfigurationError("waypoints must be finite numbers")
        steps = np.linalg.norm(np.diff(waypoints[:, :3], axis=0), axis=1)
        radius = self.parameters.neighbourhood_radius
        too_close = np.flatnonzero(steps <= radius)
        if too_close.size and not self.parameters.stop_at_waypoints:
            i = int(too_close[0])
            raise ConfigurationError(
                f"waypoints {i + 1} and {i + 2} are {steps[i]:.4f} m apart, not more than the "
                f"neighbourhood radius {radius} m"
            )
        if joint_waypoints is not None:
            joint_waypoints = np.asarray(joint_waypoints, float)
            if joint_waypoints.shape != (waypoints.shape[0], 6):
                raise ConfigurationError(
                    f"joint_waypoints must be one row of 6 joints per waypoint, got "
                    f"{joint_waypoints.shape} for {waypoints.shape[0]} waypoints"
                )
        self.waypoints = waypoints
        self.joint_waypoints = joint_waypoints
        self._poses = [
            (row[:3].copy(), RotationMatrix(RollPitchYaw(row[3:])).matrix()) for row in waypoints
        ]

    def WithWaypoints(
        self, waypoints: np.ndarray, joint_waypoints: np.ndarray | None = None
    ) -> "AccelerationPlanning":
        """The same planner (kinematics, limits, parameters) for other waypoints, and their
        joint solutions (rad, one row per waypoint, e.g. SolveWaypointIk's) for the robust
        mode's joint-space blend near singularities (off without them)."""
        planning = copy.copy(self)
        planning._SetWaypoints(waypoints, joint_waypoints)
        return planning

    def Restart(self, state: PlannerState) -> PlannerState:
        """Starts this planner's task from `state` (possibly moving): first waypoint, not
        ended, and with acceleration limits c restarts from 0 (the smooth start)."""
        state.index, state.sigma, state.inside, state.done_time = 0, 0.0, False, -1.0
        if self.scaling is not None:
            state.c_hat0, state.t0 = 0.0, state.t
        return state

    def InitialState(self, q0: np.ndarray, t: float = 0.0) -> PlannerState:
        """At rest at q0; with acceleration limits c starts at 0 (smooth start, c-hat0 = 0).
        The paper's mode raises PlanningError at a near-singular q0."""
        q0 = np.asarray(q0, float)
        if q0.shape != (6,) or not np.all(np.isfinite(q0)):
            raise ConfigurationError(f"initial joint positions must be 6 finite values: {q0}")
        self.kinematics.Evaluate(q0, np.zeros(6), analytic=not self.parameters.robust)
        c0 = 0.0 if self.scaling is not None else 1.0
        zero = np.zeros(6)
        return PlannerState(q0.copy(), zero, zero.copy(), t=t, c=c0, c_hat0=c0, t0=t)

    def Step(self, state: PlannerState) -> PlannerState:
        """The state one time step later (raises PlanningError if it cannot continue)."""
        params = self.parameters
        kin = self.kinematics.Evaluate(state.q, state.qd, analytic=not params.robust)
        state = self._AdvanceWaypoints(state, kin)
        e = self._Error(kin, self._Target(state))
        damping, inverse, sigma = 0.0, None, math.inf
        if params.robust:
            floor = max(params.damping_threshold, params.joint_space_blend[1])
            inverse, sigma = InverseAndConditioning(kin, floor)
            damping = DampingFactor(sigma, params.damping_threshold, params.max_damping)
        if self.inverse_braking is not None:
            a, b = ApproachTerms(
                kin, state.qd, e, self.approach_rates, self.inverse_braking, damping, inverse
            )
        else:
            a, b = AccelerationTerms(
                kin, state.qd, e, params.gain_p, params.gain_v, damping, inverse
            )
        if self.penalty is not None:
            b = b + self.penalty.Perturbation(state.qd)
        if params.robust and self.joint_waypoints is not None:
            a, b = self._BlendJointSpace(state, sigma, a, b)
        if params.robust:
            qdd, c, c_hat0, t0, braking = self._LimitRobust(state, a, b)
        else:
            qdd, c, c_hat0, t0, braking = (*self._LimitSeed(state, a, b), False)
        if not np.all(np.isfinite(qdd)):
            raise PlanningError(f"non-finite joint acceleration at t = {state.t:.3f} s")
        dt = params.time_step
        state.q = state.q + dt * state.qd + 0.5 * dt * dt * qdd
        state.qd = state.qd + dt * qdd
        state.qdd = qdd
        state.c, state.c_hat0, state.t0, state.braking = c, c_hat0, t0, braking
        state.t = state.t + dt
        return state

    def _LimitSeed(self, state: PlannerState, a: np.ndarray, b: np.ndarray):
        """(17) with c from the paper's scaling: (q'', c, c_hat0, t0)."""
        c, c_hat0, t0 = 1.0, state.c_hat0, state.t0
        if self.scaling is not None:
            c_free = ScalingReturn(c_hat0, state.t, t0, self.parameters.scaling_recovery_rate)
            c, limited = self.scaling.Select(a, b, c_free, state.c)
            if limited:
                c_hat0, t0 = c, state.t
        return a + c * b, c, c_hat0, t0

    def _LimitRobust(self, state: PlannerState, a: np.ndarray, b: np.ndarray):
        """(17) with the governor, the step bounds and the braking fallback, reached from
        the last acceleration at most at max_jerk: (q'', c, c_hat0, t0, braking)."""
        params = self.parameters
        if self.scaling is None and self.penalty is None:
            return a + b, 1.0, state.c_hat0, state.t0, False
        accel = (self.scaling.lower, self.scaling.upper) if self.scaling is not None else None
        velocity = (self.penalty.lower, self.penalty.upper) if self.penalty is not None else None
        lower, upper = StepBounds(accel, velocity, state.qd, params.velocity_bound_rate)
        c_hat0, t0 = state.c_hat0, state.t0
        c_free = 1.0
        if accel is not None:
            a = a + GovernorBraking(a, state.qd, *accel, params.bias_margin, params.governor_gain)
            c_free = ScalingReturn(c_hat0, state.t, t0, params.robust_recovery_rate)
        max_change = params.max_jerk * params.time_step
        c_lo, c_hi = AdmissibleScaling(a, b, lower, upper)
        if c_lo > c_hi:
            braking = BrakingAcceleration(
                state.qd, state.qdd, lower, upper, params.time_step, max_change
            )
            return braking, 0.0, 0.0, state.t, True
        c = min(max(c_free, c_lo), c_hi)
        if c != c_free:
            c_hat0, t0 = c, state.t
        qdd = JerkLimited(a + c * b, state.qdd, max_change, lower, upper)
        return qdd, c, c_hat0, t0, False

    def _BlendJointSpace(
        self, state: PlannerState, sigma: float, a: np.ndarray, b: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(a, b) blended towards the joint-space law q'' = -Lambda_V qd - Lambda_P (q - q*)
        (a = 0) by w = smoothstep of sigma over joint_space_blend; q* is the IK solution of
        the current waypoint, blended like (19) inside a neighbourhood."""
        params = self.parameters
        sigma_full, sigma_start = params.joint_space_blend
        if sigma >= sigma_start:
            return a, b
        x = min(1.0, (sigma_start - sigma) / (sigma_start - sigma_full))
        w = x * x * (3.0 - 2.0 * x)
        i = state.index
        q_target = self.joint_waypoints[i]
        if state.inside:
            q_target = q_target + state.sigma * (self.joint_waypoints[i + 1] - q_target)
        b_joint = -params.gain_v * state.qd - params.gain_p * (state.q - q_target)
        if self.penalty is not None:
            b_joint = b_joint + self.penalty.Perturbation(state.qd)
        return (1.0 - w) * a, (1.0 - w) * b + w * b_joint

    def _Target(self, state: PlannerState):
        """The location the error is measured to: p_i, or the blend (19) towards p_i+1 (a
        row in the paper's mode, an (x, R) pose in the robust mode)."""
        i = state.index
        if self.parameters.robust:
            if not state.inside:
                return self._poses[i]
            return BlendedPose(self._poses[i], self._poses[i + 1], state.sigma)
        if not state.inside:
            return self.waypoints[i]
        return BlendedTarget(self.waypoints[i], self.waypoints[i + 1], state.sigma)

    def _Error(self, kin: TcpKinematics, target) -> np.ndarray:
        if self.parameters.robust:
            return PoseError(kin, *target)
        return TrackingError(kin.p, target)

    def _Reached(self, kin: TcpKinematics, index: int) -> bool:
        params = self.parameters
        if params.robust:
            e = PoseError(kin, *self._poses[index])
            orientation = _Norm(e[3:])
        else:
            e = TrackingError(kin.p, self.waypoints[index])
            orientation = float(np.max(np.abs(e[3:])))
        return bool(
            _Norm(e[:3]) <= params.position_tolerance
            and orientation <= params.orientation_tolerance
        )

    def _AdvanceWaypoints(self, state: PlannerState, kin: TcpKinematics) -> PlannerState:
        last = len(self.waypoints) - 1
        tcp_velocity = kin.J[:3] @ state.qd
        if state.index == last:
            if not state.done and self._Reached(kin, last):
                state.done_time = state.t
            return state
        if self.parameters.stop_at_waypoints:
            resting = _Norm(tcp_velocity) <= self.parameters.rest_speed
            if resting and self._Reached(kin, state.index):
                state.index += 1
                if self.scaling is not None:  # a new elementary task starts smoothly
                    state.c_hat0, state.t0 = 0.0, state.t
            return state
        radius = self.parameters.neighbourhood_radius
        if not state.inside and _Norm(kin.x - self.waypoints[state.index, :3]) < radius:
            state.inside, state.sigma = True, 0.0
        if state.inside:
            # sigma grows with the TCP path length travelled since entering the sphere and
            # reaches 1 after blend_length: continuous in time, 0 at entry, and it keeps
            # growing whenever the TCP moves, so the TCP cannot settle at p_i.
            path = _Norm(tcp_velocity) * self.parameters.time_step
            state.sigma = min(1.0, state.sigma + path / self.parameters.blend_length)
            if state.sigma >= 1.0:
                state.index += 1
                state.inside, state.sigma = False, 0.0
        return state


def _Norm(v: np.ndarray) -> float:
    """|v| of a short vector (np.linalg.norm's dispatch costs more than the sum)."""
    return math.sqrt(float(v @ v))


def RunPlanning(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float, settle_time: float = 0.0
) -> PlannedTrajectory:
    """Runs the planner's law alone (no Diagram) from rest at q0 until settle_time after the
    task ended or until max_time (s)."""
    state = planning.InitialState(q0)
    vectors = [state.ToVector()]
    while state.t < max_time - 1e-9:
        if state.done and state.t >= state.done_time + settle_time - 1e-9:
            break
        state = planning.Step(state)
        vectors.append(state.ToVector())
    return PlannedTrajectory.FromStateVectors(np.column_stack(vectors))


def ClosestApproach(tcp_positions: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    """Smallest distance (m) of a TCP path (samples x 3) to each waypoint's position."""
    positions = np.atleast_2d(waypoints)[:, :3]
    return np.array([np.min(np.linalg.norm(tcp_positions - p, axis=1)) for p in positions])
