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
systems/planning/acceleration_planner.py wraps the law in a LeafSystem. Beside this module:
the waypoints and the blend (19) (acceleration_planner_waypoints), the robust mode's limits
(acceleration_planner_robust_limits) and its joint-space law
(acceleration_planner_joint_space).
"""

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_config import PlannerConfig
from guidedarm.systems.planning.acceleration_planner_joint_space import JointSpaceHandover
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    ArmKinematics,
    DampedSolve,
    DampingFactor,
    InverseAndConditioning,
    PlanningError,
    TcpKinematics,
)
from guidedarm.systems.planning.acceleration_planner_limits import (
    AccelerationScaling,
    ScalingReturn,
    VelocityPenalty,
)
from guidedarm.systems.planning.acceleration_planner_position_limits import PositionStepBounds
from guidedarm.systems.planning.acceleration_planner_robust_limits import (
    AdmissibleScaling,
    BrakingAcceleration,
    GovernorDamping,
    JerkWindow,
    SaturatedLeastSquares,
    SaturationMetricFactor,
    StepBounds,
)
from guidedarm.systems.planning.acceleration_planner_state import (
    PlannedTrajectory,
    PlannerState,
)
from guidedarm.systems.planning.acceleration_planner_waypoints import WaypointTracking


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


class AccelerationPlanning(WaypointTracking, JointSpaceHandover):
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
            self.reversal_limits = smallest.tolist()  # the watch's (rad/s^2)
            # The position bound falls at rate (dv/dt + q'') <= rate (b + A) while a joint
            # accelerates at A towards it: capped so that the jerk limit can follow it.
            largest = float(max(self.scaling.upper.max(), -self.scaling.lower.min()))
            jerk_rate = parameters.max_jerk / (largest * (1.0 + parameters.position_braking))
            self._position_rate = min(self._velocity_bound_rate, jerk_rate)

    def WithWaypoints(
        self, waypoints: np.ndarray, joint_waypoints: np.ndarray | None = None
    ) -> "AccelerationPlanning":
        """The same planner (kinematics, limits, parameters) for other waypoints, and their
        joint solutions (rad, one row per waypoint, e.g. SolveWaypointIk's) for the robust
        mode's joint-space blend near singularities (off without them)."""
        planning = copy.copy(self)
        planning._SetWaypoints(waypoints, joint_waypoints)
        planning.joint_space_from = None
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
        # the TCP's metric for the Cartesian law where J is undamped, else joint by joint
        if params.saturation_metric == "task" and damping == 0.0 and state.handover_time < 0:
            metric = SaturationMetricFactor(kin.J, inverse)
        qdd, _ = SaturatedLeastSquares(desired, window[0], window[1], metric)
        return qdd, c, state.c_hat0, state.t0, False


def _Floats(v: np.ndarray | list[float]) -> list[float]:
    """v as a list of floats (the robust step's limits work on floats, see StepBounds)."""
    return v.tolist() if isinstance(v, np.ndarray) else v


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
