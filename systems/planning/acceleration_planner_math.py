"""Acceleration-level trajectory planning through TCP waypoints (seed 001, Pajak).

The commanded joint acceleration of a 6-DoF arm follows the error dynamics (9)

    e'' + Lambda_V e' + Lambda_P e = 0,    e = k(q) - p_target,

with p = [x; phi] the TCP position (m) and Z-Y-X Euler angles phi = [roll, pitch, yaw]
(rad, R = Rz(yaw) Ry(pitch) Rx(roll)) of the tool frame T in the arm's base frame B. Solved
for q'' (eq. 13, 16, 17):

    q'' = a + c b,   a = -J^-1 Jdot qd,   b = -J^-1 (Lambda_V J qd + Lambda_P e) + dq''_penalty

J = diag(I, B^-1(phi)) J_g is the analytic Jacobian, J_g and Jdot_g qd come from a
MultibodyPlant (so any 6-DoF arm works), dq''_penalty is the gradient of the interior
velocity penalty (14)-(15), and c(t) is the acceleration scaling coefficient with the four
cases, the rules (a)-(c) and the exponential return (18). Waypoints are passed without
stopping by the blended target (19) inside an epsilon neighbourhood, or one after the
other with a stop at each.

Units: m, rad, s throughout. Everything here is plain Python/NumPy plus a MultibodyPlant
for kinematics; systems/planning/acceleration_planner.py wraps it in a LeafSystem.
"""

import copy
import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable, ModelInstanceIndex

from guidedarm.systems.config_checks import CheckFields, InRange, Positive
from guidedarm.systems.errors import ConfigurationError, GuidedArmError


class PlanningError(GuidedArmError):
    """The planner cannot continue (singular arm, infeasible acceleration scaling)."""


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


@dataclass
class TcpKinematics:
    """p = k(q) (m, rad), analytic Jacobian J (6 x 6) and Jdot qd (m/s^2, rad/s^2)."""

    p: np.ndarray
    J: np.ndarray
    Jdot_qdot: np.ndarray
    min_singular_value: float


class ArmKinematics:
    """k(q), J(q) and Jdot(q, qd) qd of tool frame T in base frame B from a MultibodyPlant.

    The plant may hold other models (tools, scene); only the joints of `instance` move.
    Raises PlanningError at a near-singular configuration: the smallest singular value of
    J_g below `min_singular_value`, or |pitch| within `min_singular_value` (rad) of 90 deg,
    where the Euler-angle representation itself is singular.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        instance: ModelInstanceIndex,
        base_frame: Frame,
        tool_frame: Frame,
        min_singular_value: float = 0.01,
    ) -> None:
        if plant.num_velocities(instance) != 6 or plant.num_positions(instance) != 6:
            raise ConfigurationError(
                f"the planner needs a 6-DoF arm; {plant.GetModelInstanceName(instance)} has "
                f"{plant.num_velocities(instance)} joints"
            )
        if not min_singular_value > 0:
            raise ConfigurationError(
                f"min_singular_value must be positive, got {min_singular_value}"
            )
        self.plant = plant
        self.instance = instance
        self.base_frame = base_frame
        self.tool_frame = tool_frame
        self.min_singular_value = min_singular_value
        self._context = plant.CreateDefaultContext()
        velocity_start = np.arange(plant.num_velocities())
        self._columns = plant.GetVelocitiesFromArray(instance, velocity_start).astype(int)
        self._origin = np.zeros(3)

    def Evaluate(self, q: np.ndarray, qd: np.ndarray) -> TcpKinematics:
        """Kinematics at joint positions q (rad) and velocities qd (rad/s)."""
        plant, context = self.plant, self._context
        plant.SetPositions(context, self.instance, q)
        plant.SetVelocities(context, self.instance, qd)
        X_BT = plant.CalcRelativeTransform(context, self.base_frame, self.tool_frame)
        rpy = RollPitchYaw(X_BT.rotation()).vector()
        # T's origin, measured and expressed in B, with respect to v.
        point = (JacobianWrtVariable.kV, self.tool_frame, self._origin, self.base_frame)
        Jg = plant.CalcJacobianSpatialVelocity(context, *point, self.base_frame)[:, self._columns]
        bias = plant.CalcBiasSpatialAcceleration(context, *point, self.base_frame)
        sigma = self._CheckSingularity(Jg, rpy, q)
        B_inv = EulerRateMatrixInverse(rpy)
        J = np.empty((6, 6))
        J[:3] = Jg[3:]
        J[3:] = B_inv @ Jg[:3]
        rpy_dot = J[3:] @ qd
        Jdot_qdot = np.empty(6)
        Jdot_qdot[:3] = bias.translational()
        Jdot_qdot[3:] = B_inv @ (bias.rotational() - EulerRateMatrixDotTimesRate(rpy, rpy_dot))
        p = np.empty(6)
        p[:3] = X_BT.translation()
        p[3:] = rpy
        return TcpKinematics(p, J, Jdot_qdot, sigma)

    def Position(self, q: np.ndarray) -> np.ndarray:
        """p = k(q): TCP position (m) and Z-Y-X Euler angles (rad) in the base frame."""
        self.plant.SetPositions(self._context, self.instance, q)
        X_BT = self.plant.CalcRelativeTransform(self._context, self.base_frame, self.tool_frame)
        return np.concatenate([X_BT.translation(), RollPitchYaw(X_BT.rotation()).vector()])

    def _CheckSingularity(self, Jg: np.ndarray, rpy: np.ndarray, q: np.ndarray) -> float:
        sigma = float(np.linalg.svd(Jg, compute_uv=False)[-1])
        if sigma < self.min_singular_value:
            raise PlanningError(
                f"near-singular arm configuration q={np.round(q, 4).tolist()} rad: smallest "
                f"singular value of the Jacobian {sigma:.2e} < {self.min_singular_value}"
            )
        if np.pi / 2 - abs(rpy[1]) < self.min_singular_value:
            raise PlanningError(
                f"TCP pitch {rpy[1]:.4f} rad is at the Z-Y-X Euler-angle singularity (+-pi/2)"
            )
        return sigma


def _CheckLimits(name: str, lower: np.ndarray, upper: np.ndarray) -> None:
    if lower.shape != upper.shape or lower.ndim != 1:
        raise ConfigurationError(f"{name}: lower and upper limits need the same length")
    if not np.all(np.isfinite(lower)) or not np.all(np.isfinite(upper)):
        raise ConfigurationError(f"{name}: limits must be finite")
    if np.any(upper <= 0) or np.any(lower >= 0):
        raise ConfigurationError(
            f"{name}: need lower < 0 < upper, got lower={lower.tolist()}, upper={upper.tolist()}"
        )


class VelocityPenalty:
    """Interior penalty (14) and its perturbation (15) keeping qd inside [lower, upper].

    kappa_i = rho (1/d_i - 1/theta) when the normalised distance d_i of qd_i from its
    nearer limit is below theta; dq''_i = -d kappa_i / d qd_i = rho / d_i^2 d d_i/d qd_i,
    which points away from the nearer limit and grows without bound at the limit.
    d is floored at `min_distance` so that a sampled step that lands on a limit keeps a
    finite (large) push back instead of a division by zero.
    """

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        theta: float,
        rho: float,
        min_distance: float = 1e-4,
    ) -> None:
        lower, upper = np.asarray(lower, float), np.asarray(upper, float)
        _CheckLimits("velocity limits", lower, upper)
        if not 0 < theta < 0.5:
            raise ConfigurationError(f"velocity threshold theta must be in (0, 0.5), got {theta}")
        if not rho > 0:
            raise ConfigurationError(f"penalty strength rho must be positive, got {rho}")
        self.lower, self.upper = lower, upper
        self.range = upper - lower
        self.theta = theta
        self.rho = rho
        self.min_distance = min_distance

    def Perturbation(self, qd: np.ndarray) -> np.ndarray:
        """dq'' (rad/s^2) of eq. (15); zero where every d_i >= theta."""
        to_lower = (qd - self.lower) / self.range
        to_upper = (self.upper - qd) / self.range
        d = np.maximum(np.minimum(to_lower, to_upper), self.min_distance)
        if d.min() >= self.theta:
            return np.zeros_like(qd)
        direction = np.where(to_lower < to_upper, 1.0, -1.0) / self.range
        return np.where(d < self.theta, self.rho / d**2 * direction, 0.0)


class AccelerationScaling:
    """Choice of the scaling coefficient c of q'' = a + c b under lower <= q'' <= upper.

    For each violating joint the cases (1)-(4) give an upper bound (b pushes past the
    violated limit) or a lower bound on c; rule (a) takes the smallest upper bound, (b) the
    largest lower bound, (c) the value of [c_min, c_max] nearest the previous c. Joints
    that a new c pushes past a limit join the violators and the choice is repeated, so the
    result satisfies every limit. No admissible c raises PlanningError naming the joints.
    Violators are found at trial values of c, where a case-(1)/(2) bound lies below and a
    case-(3)/(4) bound above the trial value, so rule (c) is admissible only in the
    degenerate case c_min = c_max; in practice (c) means the limits cannot be met.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray) -> None:
        lower, upper = np.asarray(lower, float), np.asarray(upper, float)
        _CheckLimits("acceleration limits", lower, upper)
        self.lower, self.upper = lower, upper

    def Select(
        self, a: np.ndarray, b: np.ndarray, c_free: float, c_previous: float
    ) -> tuple[float, bool]:
        """Returns (c, limited): c_free if it satisfies the limits, else the chosen c-hat."""
        uppers: list[float] = []
        lowers: list[float] = []
        seen = np.zeros(a.shape, bool)
        c = c_free
        for _ in range(a.size + 1):
            qdd = a + c * b
            above = (qdd > self.upper * (1 + 1e-12)) & ~seen
            below = (qdd < self.lower * (1 + 1e-12)) & ~seen
            if not (above.any() or below.any()):
                return c, bool(seen.any())
            for i in np.flatnonzero(above | below):
                if abs(b[i]) < 1e-12:
                    raise PlanningError(
                        f"acceleration limit of joint {i + 1} cannot be met by scaling: its "
                        f"unscaled part a = {a[i]:.3f} rad/s^2 alone exceeds the limit"
                    )
                limit = self.upper[i] if above[i] else self.lower[i]
                bound = (limit - a[i]) / b[i]
                # cases (1), (2): b pushes past the violated limit -> upper bound on c;
                # cases (3), (4): b pulls back -> lower bound.
                (uppers if (b[i] > 0) == bool(above[i]) else lowers).append(bound)
            seen |= above | below
            c = self._Choose(uppers, lowers, seen, c_previous)
        return c, True

    @staticmethod
    def _Choose(
        uppers: list[float], lowers: list[float], seen: np.ndarray, c_previous: float
    ) -> float:
        if not lowers:
            return min(uppers)  # rule (a)
        if not uppers:
            return max(lowers)  # rule (b)
        c_min, c_max = max(lowers), min(uppers)  # rule (c)
        if c_min > c_max:
            joints = ", ".join(str(i + 1) for i in np.flatnonzero(seen))
            raise PlanningError(
                f"acceleration scaling case (c) has no admissible c (joints {joints}: "
                f"c_min {c_min:.4f} > c_max {c_max:.4f})"
            )
        return float(np.clip(c_previous, c_min, c_max))


@dataclass
class PlannerConfig:
    """Gains and settings of the planner (defaults: the seed's values where it gives them).

    gain_p, gain_v: Lambda_P (1/s^2) and Lambda_V (1/s), equal on all six error axes.
    neighbourhood_radius: epsilon of (19) (m). position_tolerance: TCP accuracy that ends
        the task (m); orientation_tolerance: the same for the Euler angles (rad).
    velocity_threshold: theta of (14). penalty_strength: rho of (14) (rad/s^2 times the
        normalised velocity range); 0.003 because (15) switches on with a step of
        c rho / (theta^2 range) in q'', which stays below the per-step change the
        scaling itself makes (< 0.07 rad/s^2 at 500 Hz on the seed's task), while a
        weaker barrier (rho = 0.001) is so stiff at 500 Hz that, unscaled, it chatters.
    scaling_recovery_rate: rate of the exponential return (18) of c to 1 (1/s).
    stop_at_waypoints: stop at every waypoint instead of blending through it; the next
        elementary task starts once the TCP is within the tolerances and slower than
        rest_speed, i.e. practically at rest as boundary condition (3) asks.
    rest_speed: the TCP speed below which it counts as at rest (m/s).
    time_step: planner period (s), 0.002 s = 500 Hz as UR servoJ.
    min_singular_value: smallest admissible singular value of J_g before the planner
        stops with an error (m or rad per rad).
    blend_length: TCP path length (m) over which sigma of (19) goes from 0 to 1 once the
        TCP is inside a neighbourhood; the radius itself by default (the seed leaves the
        law open; docs/planner.md compares the choices against Table 2).
    """

    gain_p: float = Positive(20.0)
    gain_v: float = Positive(9.392)
    neighbourhood_radius: float = Positive(0.05)
    position_tolerance: float = Positive(0.001)
    orientation_tolerance: float = Positive(0.001)
    velocity_threshold: float = InRange(0.0, 0.5, 0.1, low_open=True, high_open=True)
    penalty_strength: float = Positive(0.003)
    scaling_recovery_rate: float = Positive(1.0)
    stop_at_waypoints: bool = False
    rest_speed: float = Positive(0.001)
    time_step: float = Positive(0.002)
    min_singular_value: float = Positive(0.01)
    blend_length: float = Positive(0.05)

    def Validate(self) -> None:
        """Raises ConfigurationError for a gain or setting out of its bounds."""
        CheckFields(self)


@dataclass
class PlannerTask:
    """A task given to a running planner: `waypoints` rows [x, y, z, roll, pitch, yaw] of
    the TCP T in the base frame B (m, rad, Z-Y-X Euler angles), the last one the final
    location. A `sequence` number different from the running task's restarts the law with
    these waypoints; a negative one means no task."""

    sequence: int = -1
    waypoints: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))


@dataclass
class PlannerState:
    """Everything the planner carries from one step to the next.

    q, qd: commanded joint positions (rad) and velocities (rad/s) at time t (s); qdd: the
    acceleration applied over the step that ended at t (rad/s^2). c: scaling coefficient of
    that step; c_hat0, t0: start value and time of the exponential return (18). index: the
    waypoint the TCP moves towards; sigma: blending progress in its neighbourhood,
    inside = 1 while blending; done_time: first time the task
    ended (s), -1 before.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    t: float = 0.0
    c: float = 1.0
    c_hat0: float = 1.0
    t0: float = 0.0
    index: int = 0
    sigma: float = 0.0
    inside: bool = False
    done_time: float = -1.0

    SIZE_EXTRA = 8
    TIME_ROW = 18  # row of t in ToVector() of a 6-joint arm

    def ToVector(self) -> np.ndarray:
        scalars = [self.t, self.c, self.c_hat0, self.t0, self.index, self.sigma]
        scalars += [float(self.inside), self.done_time]
        return np.concatenate([self.q, self.qd, self.qdd, scalars])

    @staticmethod
    def FromVector(x: np.ndarray) -> "PlannerState":
        n = (x.size - PlannerState.SIZE_EXTRA) // 3
        t, c, c_hat0, t0, index, sigma, inside, done_time = x[3 * n :]
        return PlannerState(
            x[:n].copy(), x[n : 2 * n].copy(), x[2 * n : 3 * n].copy(), float(t), float(c),
            float(c_hat0), float(t0), round(index), float(sigma),
            bool(inside > 0.5), float(done_time),
        )  # fmt: skip

    @property
    def done(self) -> bool:
        return self.done_time >= 0


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
    ) -> None:
        parameters.Validate()
        self.kinematics = kinematics
        self.parameters = parameters
        self.waypoints = self._CheckWaypoints(waypoints)
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

    def _CheckWaypoints(self, waypoints: np.ndarray) -> np.ndarray:
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
        return waypoints

    def WithWaypoints(self, waypoints: np.ndarray) -> "AccelerationPlanning":
        """The same planner (kinematics, limits, parameters) for other waypoints."""
        planning = copy.copy(self)
        planning.waypoints = self._CheckWaypoints(waypoints)
        return planning

    def Restart(self, state: PlannerState) -> PlannerState:
        """Starts this planner's task from `state` (possibly moving): first waypoint, not
        ended, and with acceleration limits c restarts from 0 (the smooth start)."""
        state.index, state.sigma, state.inside, state.done_time = 0, 0.0, False, -1.0
        if self.scaling is not None:
            state.c_hat0, state.t0 = 0.0, state.t
        return state

    def InitialState(self, q0: np.ndarray, t: float = 0.0) -> PlannerState:
        """At rest at q0; with acceleration limits c starts at 0 (smooth start, c-hat0 = 0)."""
        q0 = np.asarray(q0, float)
        if q0.shape != (6,) or not np.all(np.isfinite(q0)):
            raise ConfigurationError(f"initial joint positions must be 6 finite values: {q0}")
        self.kinematics.Evaluate(q0, np.zeros(6))
        c0 = 0.0 if self.scaling is not None else 1.0
        zero = np.zeros(6)
        return PlannerState(q0.copy(), zero, zero.copy(), t=t, c=c0, c_hat0=c0, t0=t)

    def Target(self, state: PlannerState) -> np.ndarray:
        """The location the error is measured to: p_i, or the blend (19) towards p_i+1."""
        current = self.waypoints[state.index]
        if not state.inside:
            return current
        following = self.waypoints[state.index + 1]
        delta = following - current
        delta[3:] = WrapAngle(delta[3:])
        return current + state.sigma * delta

    def Error(self, p: np.ndarray, target: np.ndarray) -> np.ndarray:
        """e = k(q) - target with the Euler-angle part wrapped (m, rad)."""
        e = p - target
        e[3:] = WrapAngle(e[3:])
        return e

    def Step(self, state: PlannerState) -> PlannerState:
        """The state one time step later (raises PlanningError if it cannot continue)."""
        params = self.parameters
        kin = self.kinematics.Evaluate(state.q, state.qd)
        state = self._AdvanceWaypoints(state, kin.p, kin.J[:3] @ state.qd)
        e = self.Error(kin.p, self.Target(state))
        rhs = np.empty((6, 2))
        rhs[:, 0] = kin.Jdot_qdot
        rhs[:, 1] = params.gain_v * (kin.J @ state.qd) + params.gain_p * e
        solved = np.linalg.solve(kin.J, rhs)
        a, b = -solved[:, 0], -solved[:, 1]
        if self.penalty is not None:
            b = b + self.penalty.Perturbation(state.qd)
        c, c_hat0, t0 = 1.0, state.c_hat0, state.t0
        if self.scaling is not None:
            c_free = (c_hat0 - 1.0) * np.exp(-params.scaling_recovery_rate * (state.t - t0)) + 1
            c, limited = self.scaling.Select(a, b, c_free, state.c)
            if limited:
                c_hat0, t0 = c, state.t
        qdd = a + c * b
        if not np.all(np.isfinite(qdd)):
            raise PlanningError(f"non-finite joint acceleration at t = {state.t:.3f} s")
        dt = params.time_step
        state.q = state.q + dt * state.qd + 0.5 * dt * dt * qdd
        state.qd = state.qd + dt * qdd
        state.qdd = qdd
        state.c, state.c_hat0, state.t0 = c, c_hat0, t0
        state.t = state.t + dt
        return state

    def _Reached(self, p: np.ndarray, index: int) -> bool:
        e = self.Error(p, self.waypoints[index])
        return bool(
            np.linalg.norm(e[:3]) <= self.parameters.position_tolerance
            and np.max(np.abs(e[3:])) <= self.parameters.orientation_tolerance
        )

    def _AdvanceWaypoints(
        self, state: PlannerState, p: np.ndarray, tcp_velocity: np.ndarray
    ) -> PlannerState:
        last = len(self.waypoints) - 1
        if state.index == last:
            if not state.done and self._Reached(p, last):
                state.done_time = state.t
            return state
        if self.parameters.stop_at_waypoints:
            resting = np.linalg.norm(tcp_velocity) <= self.parameters.rest_speed
            if resting and self._Reached(p, state.index):
                state.index += 1
                if self.scaling is not None:  # a new elementary task starts smoothly
                    state.c_hat0, state.t0 = 0.0, state.t
            return state
        radius = self.parameters.neighbourhood_radius
        if not state.inside and np.linalg.norm(p[:3] - self.waypoints[state.index, :3]) < radius:
            state.inside, state.sigma = True, 0.0
        if state.inside:
            # sigma grows with the TCP path length travelled since entering the sphere and
            # reaches 1 after blend_length: continuous in time, 0 at entry, and it keeps
            # growing whenever the TCP moves, so the TCP cannot settle at p_i.
            path = np.linalg.norm(tcp_velocity) * self.parameters.time_step
            state.sigma = min(1.0, state.sigma + path / self.parameters.blend_length)
            if state.sigma >= 1.0:
                state.index += 1
                state.inside, state.sigma = False, 0.0
        return state


@dataclass
class PlannedTrajectory:
    """A commanded trajectory sampled at the planner period: times (s), q, qd, qdd
    (samples x 6; rad, rad/s, rad/s^2), c and the waypoint index per sample, and the time
    the task ended (s; -1 if it did not)."""

    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    c: np.ndarray
    index: np.ndarray
    done_time: float

    @staticmethod
    def FromStateVectors(columns: np.ndarray) -> "PlannedTrajectory":
        """From PlannerState vectors, one per column (e.g. a VectorLog of them)."""
        n = (columns.shape[0] - PlannerState.SIZE_EXTRA) // 3
        extra = columns[3 * n :]
        done = extra[7][extra[7] >= 0]
        return PlannedTrajectory(
            times=extra[0].copy(),
            q=columns[:n].T.copy(),
            qd=columns[n : 2 * n].T.copy(),
            qdd=columns[2 * n : 3 * n].T.copy(),
            c=extra[1].copy(),
            index=extra[4].round().astype(int),
            done_time=float(done[0]) if done.size else -1.0,
        )


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
