"""The acceleration-level planner's waypoints: the target the error is measured to, the
blend (19) that passes a waypoint without stopping, and the bookkeeping of which waypoint
the TCP is going to (Pająk; acceleration_planner_math has the law).

Units: m, rad, s; waypoint rows [x, y, z, roll, pitch, yaw] of the TCP T in the base frame.
"""

import math

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    BlendedPose,
    BlendedTarget,
    PoseError,
    RotationVector,
    TcpKinematics,
    TrackingError,
)
from guidedarm.systems.planning.acceleration_planner_state import PlannerState
from guidedarm.systems.small_vectors import Distance


class WaypointTracking:
    """AccelerationPlanning's waypoint part (a base class of it): sets `waypoints`,
    `joint_waypoints` and their poses, and reads the planner's `parameters` and `scaling`."""

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
        if not state.inside and Distance(kin.x, self._poses[state.index][0]) < radius:
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


def _Norm(v: np.ndarray) -> float:
    """|v| of a 3-vector (scalar arithmetic: NumPy's dispatch costs more than the sum)."""
    x, y, z = v.tolist()
    return math.sqrt(x * x + y * y + z * z)
