"""The robust planner's joint-space law (beyond the paper): blended in near singularities,
and taking over for the rest of a task when the Cartesian law nears a joint's position
limit, makes no progress or oscillates (acceleration_planner_watch measures both), or from
a chosen waypoint on (WithJointSpaceFrom: where the Cartesian motion would touch the cell).

The joint-space law q'' = -Lambda_V qd - Lambda_P (q - q*) drives the joints to the
waypoints' IK solutions q* (the planner's `joint_waypoints`). Units: rad, s.
"""

import copy

import numpy as np

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import PlanningError
from guidedarm.systems.planning.acceleration_planner_state import PlannerState
from guidedarm.systems.planning.acceleration_planner_watch import (
    Progressed,
    TargetError,
    UpdateReversals,
)


class JointSpaceHandover:
    """AccelerationPlanning's joint-space part (a base class of it): reads the planner's
    `parameters`, `joint_waypoints`, `inverse_braking`, `penalty`, `position_bounds`,
    `reversal_limits` and `joint_space_from` (the waypoint a joint-space route starts at,
    AccelerationPlanning.WithJointSpaceFrom; None for none)."""

    joint_space_from: int | None = None  # the waypoint a joint-space route starts at

    def WithJointSpaceFrom(
        self, index: int, joint_waypoints: np.ndarray | None = None
    ) -> "JointSpaceHandover":
        """The same planner and task routed through joint space from waypoint `index`
        (0-based; 0: from the start): the law hands over to joint space (item 10 of
        docs/planner.md, towards the waypoints' IK solutions) as soon as it heads for that
        waypoint, for the rest of the task; towards `joint_waypoints` (rad, one row per
        waypoint, e.g. another IK branch, WaypointIkBranches) when given, else the
        planner's own. The robust mode with acceleration limits and joint waypoints only
        (the hand-over's law needs both)."""
        if self.position_bounds is None or self.joint_waypoints is None:
            raise ConfigurationError(
                "a joint-space route needs the robust mode, acceleration limits and the "
                "waypoints' joint solutions"
            )
        if not 0 <= index < len(self.waypoints):
            raise ConfigurationError(f"no waypoint {index + 1} to route from")
        planning = copy.copy(self)
        planning.joint_space_from = index
        if joint_waypoints is not None:
            joint_waypoints = np.asarray(joint_waypoints, float)
            if joint_waypoints.shape != self.joint_waypoints.shape:
                raise ConfigurationError(
                    f"a joint-space route needs one row of 6 joints per waypoint, got "
                    f"{joint_waypoints.shape} for {len(self.waypoints)} waypoints"
                )
            planning.joint_waypoints = joint_waypoints
        return planning

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
        joint-space route reaching its waypoint (joint_space_from), a joint within
        limit_blend of a position limit and moving towards it, or no progress for half of
        stall_time, hands the law over to joint space for the rest of the task
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
            routed = self.joint_space_from is not None and state.index >= self.joint_space_from
            if routed or stalled > 0.5 * params.stall_time or self._NearLimit(state):
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
            self.reversal_limits,
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
