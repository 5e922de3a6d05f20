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
  that keep qd within its limits at every step, per-joint saturation (a joint that would
  leave its bounds is held at its bound, the others keep their share of the law instead of
  c scaling the task for all; SaturatedLeastSquares), and a braking fallback should no
  admissible c exist all the same; c then restarts from 0 as at the smooth start.

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
    RotationVector,
    TcpKinematics,
    TrackingError,
)
from guidedarm.systems.planning.acceleration_planner_limits import (
    AccelerationScaling,
    AdmissibleScaling,
    BrakingAcceleration,
    GovernorDamping,
    JerkWindow,
    SaturatedLeastSquares,
    SaturationMetricFactor,
    ScalingReturn,
    StepBounds,
    VelocityPenalty,
)
from guidedarm.systems.planning.acceleration_planner_position_limits import PositionStepBounds
from guidedarm.systems.planning.acceleration_planner_state import (
    PlannedTrajectory,
    PlannerState,
)
from guidedarm.systems.planning.acceleration_planner_watch import (
    Progressed,
    TargetError,
    UpdateReversals,
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
    inverse_braking: list[float],
    damping: float = 0.0,
    inverse: np.ndarray | None = None,
) -> tuple[list[float], list[float]]:
    """The robust mode's (a, b) (rad/s^2, as floats for the robust step's limits) with the
    braking approach: the error dynamics
    e'' = -(k + r) e' - (k r + r') e, i.e. e' tracks -r e at the rate k. (9) is this with
    constants r = r0 and k = k0, its roots (rates = (r0, k0, r_max), 1/s). Here
    r = sqrt(r0^2 + h), h = 2 / (d + 2 / (r_max^2 - r0^2)), grows as the joint
    displacement to go u = J^-1 e shrinks, d = ||u * inverse_braking||_4 (s^2;
    inverse_braking = 1 / (eta A) per joint, s^2/rad): a joint u_i from the target moves at
    most about sqrt(2 eta A_i u_i), the speed from which braking at eta A_i stops it there
    (the square-root law of time-optimal braking), r0 far away, r_max at the target; k
    rises with r in proportion (k = k0 r / r0), so the slower root is r, not k0. r' follows
    d' = grad d . qd (u' = qd to first order), so q'' stays continuous in the state."""
    if damping == 0.0 and inverse is not None:
        # J^-1 J qd = qd: two products instead of three
        minus_a, v, u = inverse.dot(kin.Jdot_qdot), qd, inverse.dot(e)
    else:
        rhs = np.empty((6, 3))
        rhs[:, 0] = kin.Jdot_qdot
        rhs[:, 1] = kin.J @ qd
        rhs[:, 2] = e
        solved = DampedSolve(kin.J, rhs, damping, inverse)
        minus_a, v, u = solved[:, 0], solved[:, 1], solved[:, 2]
    r0, k0, r_max = rates
    # d and its rate in scalar arithmetic (six joints cost less than NumPy's calls)
    x4_sum, rate_sum = 0.0, 0.0
    u_list, qd_list = u.tolist(), qd.tolist()
    for u_i, w_i, qd_i in zip(u_list, inverse_braking, qd_list):
        x = u_i * w_i  # |x| the joint's term of d (w_i > 0)
        x2 = x * x
        x4_sum += x2 * x2
        rate_sum += x2 * x * w_i * qd_i
    d = x4_sum**0.25
    if d < 1e-12:
        r, r_dot = r_max, 0.0
    else:
        h = 2.0 / (d + 2.0 / (r_max * r_max - r0 * r0))
        r = math.sqrt(r0 * r0 + h)
        r_dot = -0.25 * h * h / r * rate_sum / (d * d * d)
    k = k0 * r / r0
    gain_v, gain_p = k + r, k * r + r_dot
    v_list = qd_list if v is qd else v.tolist()
    b = [-gain_v * v_i - gain_p * u_i for v_i, u_i in zip(v_list, u_list)]
    return [-m for m in minus_a.tolist()], b


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
        self._time_steps = (
            np.full(6, parameters.time_step),
            np.full(6, 0.5 * parameters.time_step),
        )
        # below it the robust step needs the smallest singular value itself
        self._conditioning_floor = max(
            parameters.damping_threshold, parameters.joint_space_blend[1]
        )
        # the robust step's limits as floats (see StepBounds)
        self._acceleration_bounds = (
            (self.scaling.lower.tolist(), self.scaling.upper.tolist()) if self.scaling else None
        )
        self._velocity_bounds = (
            (self.penalty.lower.tolist(), self.penalty.upper.tolist()) if self.penalty else None
        )
        # The step bound near a velocity limit falls at rate x q'' (StepBounds): capped so
        # that the jerk limit can follow it.
        self._velocity_bound_rate = parameters.velocity_bound_rate
        if self.scaling:
            largest = float(max(self.scaling.upper.max(), -self.scaling.lower.min()))
            jerk_rate = parameters.max_jerk / largest
            self._velocity_bound_rate = min(self._velocity_bound_rate, jerk_rate)
        self.inverse_braking = None
        if parameters.robust and parameters.approach_acceleration > 0 and self.scaling:
            braking = np.minimum(self.scaling.upper, -self.scaling.lower)
            self.inverse_braking = (1.0 / (parameters.approach_acceleration * braking)).tolist()
            r0 = parameters.SlowRoot()
            self.approach_rates = (r0, parameters.gain_v - r0, parameters.approach_rate)
        # the robust mode's position limits and watch need a finite braking acceleration
        self.position_bounds = None
        if parameters.robust and self.scaling is not None:
            lower, upper = kinematics.PositionLimits()
            margin = parameters.joint_limit_margin
            smallest = np.minimum(self.scaling.upper, -self.scaling.lower)
            self.position_bounds = (
                (lower + margin).tolist(),
                (upper - margin).tolist(),
                (parameters.position_braking * smallest).tolist(),
            )
            self._reversal_limits = smallest.tolist()
            # The position bound falls at rate (dv/dt + q'') <= rate (b + A) while a joint
            # accelerates at A towards it: capped so that the jerk limit can follow it.
            largest = float(max(self.scaling.upper.max(), -self.scaling.lower.min()))
            jerk_rate = parameters.max_jerk / (largest * (1.0 + parameters.position_braking))
            self._position_rate = min(self._velocity_bound_rate, jerk_rate)

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
            (row[:3].tolist(), RotationMatrix(RollPitchYaw(row[3:])).matrix()) for row in waypoints
        ]
        # log(R_i^T R_i+1) of each pair, the geodesic of the blend (19), once per task
        self._pair_rotations = [
            RotationVector(R_i.T @ R_next)
            for (_, R_i), (_, R_next) in zip(self._poses[:-1], self._poses[1:], strict=True)
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
        state.handover_time, state.best_error, state.best_progress = -1.0, 1e9, 0.0
        state.best_time = state.t
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
        return PlannerState(q0.copy(), zero, zero.copy(), t=t, c=c0, c_hat0=c0, t0=t, best_time=t)

    def Step(self, state: PlannerState) -> PlannerState:
        """The state one time step later (raises PlanningError if it cannot continue)."""
        params = self.parameters
        kin = self.kinematics.Evaluate(state.q, state.qd, analytic=not params.robust)
        state, e = self._AdvanceWaypoints(state, kin)
        if e is None:
            e = self._Error(kin, self._Target(state))
        damping, inverse, sigma = 0.0, None, math.inf
        if params.robust:
            inverse, sigma = InverseAndConditioning(kin, self._conditioning_floor)
            if inverse is None:  # else sigma >= the floor >= damping_threshold: no damping
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
            penalty = self.penalty.Perturbation(state.qd)
            if penalty is not self.penalty.zero:
                b = b + penalty
        if self.position_bounds is not None:
            self._Watch(state, e)
        if params.robust and self.joint_waypoints is not None:
            a, b = self._BlendJointSpace(state, sigma, a, b)
        if params.robust:
            qdd, c, c_hat0, t0, braking = self._LimitRobust(state, a, b, kin, damping, inverse)
        else:
            qdd, c, c_hat0, t0, braking = (*self._LimitSeed(state, a, b), False)
        if not math.isfinite(sum(_Floats(qdd))):  # NaN or inf in a joint
            raise PlanningError(f"non-finite joint acceleration at t = {state.t:.3f} s")
        if self.position_bounds is not None:
            self._WatchOscillation(state, _Floats(qdd))
        qdd = np.asarray(qdd, float)
        # q'' held over the step; times arrays of dt, which cost less than a float's
        # conversion in each product
        dt, half_dt = self._time_steps  # arrays
        qd_next = state.qd + qdd * dt
        state.q = state.q + (state.qd + qd_next) * half_dt
        state.qd = qd_next
        state.qdd = qdd
        state.c, state.c_hat0, state.t0, state.braking = c, c_hat0, t0, braking
        state.t = state.t + params.time_step
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

    def _LimitRobust(
        self,
        state: PlannerState,
        a: np.ndarray,
        b: np.ndarray,
        kin: TcpKinematics,
        damping: float,
        inverse: np.ndarray | None,
    ):
        """(17) with the governor, the step bounds, per-joint saturation and the braking
        fallback, reached from the last acceleration at most at max_jerk:
        (q'', c, c_hat0, t0, braking). c is the smooth start's return (18) and is not cut
        by the limits: a joint whose a + c b leaves its bounds is held at its bound and the
        others keep their share of the law (SaturatedLeastSquares)."""
        params = self.parameters
        accel, velocity = self._acceleration_bounds, self._velocity_bounds
        if accel is None and velocity is None:
            qdd = [a_i + b_i for a_i, b_i in zip(_Floats(a), _Floats(b))]
            return qdd, 1.0, state.c_hat0, state.t0, False
        qd, qdd_previous, a, b = state.qd.tolist(), state.qdd.tolist(), _Floats(a), _Floats(b)
        lower, upper = StepBounds(accel, velocity, qd, self._velocity_bound_rate)
        if self.position_bounds is not None:
            lower, upper = PositionStepBounds(
                state.q.tolist(), qd, lower, upper, *self.position_bounds, self._position_rate,
            )  # fmt: skip
        c = 1.0
        if accel is not None:
            d = GovernorDamping(a, qd, *accel, params.bias_margin, params.governor_gain)
            if d > 0.0:
                a = [a_i - d * qd_i for a_i, qd_i in zip(a, qd)]
            c = ScalingReturn(state.c_hat0, state.t, state.t0, params.robust_recovery_rate)
        max_change = params.max_jerk * params.time_step
        desired = [a_i + c * b_i for a_i, b_i in zip(a, b)]
        window = JerkWindow(desired, qdd_previous, max_change, lower, upper)
        if window[2]:  # within the bounds at this c: no saturation, no braking
            return desired, c, state.c_hat0, state.t0, False
        c_lo, c_hi = AdmissibleScaling(a, b, lower, upper)
        if c_lo > c_hi:  # no scaling of the law meets the bounds: brake
            braking = BrakingAcceleration(
                qd, qdd_previous, lower, upper, params.time_step, max_change
            )
            return braking, 0.0, 0.0, state.t, True
        metric = None
        # the TCP's metric where J is well conditioned, joint by joint where it is damped
        if params.saturation_metric == "task" and damping == 0.0:
            metric = SaturationMetricFactor(kin.J, inverse)
        qdd, _ = SaturatedLeastSquares(desired, window[0], window[1], metric)
        return qdd, c, state.c_hat0, state.t0, False

    def _BlendJointSpace(
        self, state: PlannerState, sigma: float, a: np.ndarray, b: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(a, b) blended towards the joint-space law q'' = -Lambda_V qd - Lambda_P (q - q*)
        (a = 0; with the braking approach on, _JointSpaceApproach) by w = smoothstep of
        sigma over joint_space_blend, or over handover_ramp once the law is handed over to
        joint space for the rest of the task (_Watch); q* is the IK solution of the current
        waypoint, blended like (19) inside a neighbourhood."""
        params = self.parameters
        sigma_full, sigma_start = params.joint_space_blend
        w = 0.0
        if sigma < sigma_start:
            w = _SmoothStep((sigma_start - sigma) / (sigma_start - sigma_full))
        if state.handover_time >= 0:
            w = max(w, _SmoothStep((state.t - state.handover_time) / params.handover_ramp))
        if w == 0.0:
            return a, b
        i = state.index
        q_target = self.joint_waypoints[i]
        if state.inside:
            q_target = q_target + state.sigma * (self.joint_waypoints[i + 1] - q_target)
        u = state.q - q_target
        if self.inverse_braking is None:
            b_joint = -params.gain_v * state.qd - params.gain_p * u
        else:
            b_joint = self._JointSpaceApproach(state.qd, u)
        if self.penalty is not None:
            b_joint = b_joint + self.penalty.Perturbation(state.qd)
        return (1.0 - w) * np.asarray(a), (1.0 - w) * np.asarray(b) + w * b_joint

    def _JointSpaceApproach(self, qd: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The joint-space law with the braking approach on (rad/s^2): qd tracks, at the rate
        k = approach_rate, the speed towards the target v = sqrt(2 eta A |u| + c^2) - c with
        c = eta A / r and r = k / 4 (the square-root law of braking at eta A far away, so a
        joint whose acceleration saturates brakes in time instead of overshooting; the
        exponential rate r near the target, k = 4 r making the loop critically damped),
        u = q - q* the joints' distance to their target (rad)."""
        k = self.parameters.approach_rate
        braking = 1.0 / np.asarray(self.inverse_braking)
        c = braking / (0.25 * k)
        speed = np.sqrt(2.0 * braking * np.abs(u) + c * c) - c
        return -k * (qd + np.sign(u) * speed)

    def _Watch(self, state: PlannerState, e: np.ndarray) -> None:
        """The hand-over to joint space and the progress watch (PlannedState's best_*): a
        joint within limit_blend of a position limit and moving towards it, or no progress
        for half of stall_time, hands the law over to joint space for the rest of the task
        (where the waypoints' IK solutions are known); no progress for stall_time stops the
        planner with a PlanningError."""
        params, t = self.parameters, state.t
        latched = state.handover_time >= 0
        if latched:
            error = float(np.linalg.norm(state.q - self.joint_waypoints[state.index]))
        else:
            error = TargetError(e.tolist())
        progressed, state.best_error, state.best_progress = Progressed(
            error, state.index + state.sigma, state.best_error, state.best_progress
        )
        if progressed or state.done:
            state.best_time = t
        stalled = t - state.best_time
        if not latched and self.joint_waypoints is not None:
            if stalled > 0.5 * params.stall_time or self._NearLimit(state):
                _HandOver(state)
            return
        if stalled > params.stall_time:
            what = "rad from its joint solution" if latched else "m from it (pose error)"
            raise PlanningError(
                f"no progress towards waypoint {state.index + 1} for {stalled:.1f} s "
                f"(planner.stall_time): {error:.4f} {what}"
            )

    def _NearLimit(self, state: PlannerState) -> bool:
        """Whether a joint is within limit_blend of a position limit, moving towards it."""
        reach = self.parameters.limit_blend
        lower, upper, _ = self.position_bounds
        for q_i, qd_i, lo, hi in zip(state.q.tolist(), state.qd.tolist(), lower, upper):
            if (qd_i > 0.0 and hi - q_i < reach) or (qd_i < 0.0 and q_i - lo < reach):
                return True
        return False

    def _WatchOscillation(self, state: PlannerState, qdd: list[float]) -> None:
        """The oscillation measure's step (UpdateReversals): a joint reversing faster than
        max_reversal_rate hands the law over to joint space for the rest of the task, or,
        once handed over (or without joint solutions), stops the planner with a
        PlanningError naming it."""
        signs, rates = UpdateReversals(
            qdd,
            self._reversal_limits,
            state.reversal_sign.tolist(),
            state.reversal_rate.tolist(),
            self.parameters.time_step,
        )
        state.reversal_sign, state.reversal_rate = np.array(signs), np.array(rates)
        worst = max(rates)
        if worst > self.parameters.max_reversal_rate:
            if state.handover_time < 0 and self.joint_waypoints is not None:
                # the Cartesian law struggles: hand over to joint space, whose error dynamics
                # towards the joint solution do not swing
                _HandOver(state)
                return
            joint = rates.index(worst) + 1
            raise PlanningError(
                f"joint {joint} oscillates at t = {state.t:.2f} s: its commanded acceleration "
                f"reversed {worst:.1f} times per second (planner.max_reversal_rate "
                f"{self.parameters.max_reversal_rate})"
            )

    def _Target(self, state: PlannerState):
        """The location the error is measured to: p_i, or the blend (19) towards p_i+1 (a
        row in the paper's mode, an (x, R) pose in the robust mode)."""
        i = state.index
        if self.parameters.robust:
            if not state.inside:
                return self._poses[i]
            return BlendedPose(
                self._poses[i], self._poses[i + 1], state.sigma, self._pair_rotations[i]
            )
        if not state.inside:
            return self.waypoints[i]
        return BlendedTarget(self.waypoints[i], self.waypoints[i + 1], state.sigma)

    def _Error(self, kin: TcpKinematics, target) -> np.ndarray:
        if self.parameters.robust:
            return PoseError(kin, *target)
        return TrackingError(kin.p, target)

    def _Reached(self, kin: TcpKinematics, index: int, e: np.ndarray) -> bool:
        """The TCP within the tolerances of waypoint `index`, e the error to it."""
        params = self.parameters
        if _Norm(e[:3]) > params.position_tolerance:
            return False
        orientation = _Norm(e[3:]) if params.robust else float(np.max(np.abs(e[3:])))
        return orientation <= params.orientation_tolerance

    def _AdvanceWaypoints(
        self, state: PlannerState, kin: TcpKinematics
    ) -> tuple[PlannerState, np.ndarray | None]:
        """The waypoint bookkeeping, and the error to the last waypoint once the TCP moves
        towards it (None before: the target then depends on the bookkeeping)."""
        last = len(self.waypoints) - 1
        if state.index == last:
            e = self._Error(kin, self._Target(state))
            if not state.done and self._Reached(kin, last, e):
                state.done_time = state.t
            return state, e
        if self.parameters.stop_at_waypoints:
            resting = _Norm(kin.J[:3].dot(state.qd)) <= self.parameters.rest_speed
            if resting and self._Reached(kin, state.index, self._Error(kin, self._Target(state))):
                state.index += 1
                if self.scaling is not None:  # a new elementary task starts smoothly
                    state.c_hat0, state.t0 = 0.0, state.t
            return state, None
        radius = self.parameters.neighbourhood_radius
        if not state.inside and _Distance(kin.x, self._poses[state.index][0]) < radius:
            state.inside, state.sigma = True, 0.0
        if state.inside:
            # sigma grows with the TCP path length travelled since entering the sphere and
            # reaches 1 after blend_length: continuous in time, 0 at entry, and it keeps
            # growing whenever the TCP moves, so the TCP cannot settle at p_i.
            path = _Norm(kin.J[:3].dot(state.qd)) * self.parameters.time_step
            state.sigma = min(1.0, state.sigma + path / self.parameters.blend_length)
            if state.sigma >= 1.0:
                state.index += 1
                state.inside, state.sigma = False, 0.0
        return state, None


def _HandOver(state: PlannerState) -> None:
    """Hands the law over to joint space for the rest of the task from now: the progress
    watch and the oscillation measure restart with the new law (the Cartesian law's
    reversals before it are not the joint-space law's)."""
    state.handover_time, state.best_error, state.best_time = state.t, 1e9, state.t
    state.reversal_rate = np.zeros(state.reversal_rate.size)


def _SmoothStep(x: float) -> float:
    """3 x^2 - 2 x^3 of x clipped to [0, 1]."""
    x = 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)
    return x * x * (3.0 - 2.0 * x)


def _Floats(v: np.ndarray | list[float]) -> list[float]:
    """v as a list of floats (the robust step's limits work on floats, see StepBounds)."""
    return v.tolist() if isinstance(v, np.ndarray) else v


def _Distance(x: list[float], y: list[float]) -> float:
    """|x - y| of two points given as three floats each (m)."""
    dx, dy, dz = x[0] - y[0], x[1] - y[1], x[2] - y[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def _Norm(v: np.ndarray) -> float:
    """|v| of a 3-vector (scalar arithmetic: NumPy's dispatch costs more than the sum)."""
    x, y, z = v.tolist()
    return math.sqrt(x * x + y * y + z * z)


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
