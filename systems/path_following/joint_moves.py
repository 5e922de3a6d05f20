"""Rest-to-rest joint-space moves of the path follower, through joint waypoints.

Each segment is a straight line in joint space timed by a trapezoidal profile of its path
parameter s in [0, 1]: the tool centre cruises at tool_speed and no joint exceeds
max_joint_speed, and both start and stop with bounded acceleration (tool_acceleration,
max_joint_acceleration). A commanded velocity that jumps from zero to cruise in one tick
would be refused by a real controller (and by the hardware command guard); a bounded
acceleration is what every industrial controller's own point-to-point move does. The arm
stops at every waypoint, where the follower reads its sensors anyway.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from guidedarm.systems.config_checks import CheckFields, Positive


@dataclass(frozen=True)
class MotionLimits:
    """tool_speed (m/s), max_joint_speed (rad/s), tool_acceleration (m/s^2),
    max_joint_acceleration (rad/s^2), settle_tolerance (rad), settle_timeout (s); all > 0."""

    tool_speed: float = Positive(0.05)
    max_joint_speed: float = Positive(1.0)
    tool_acceleration: float = Positive(0.5)
    max_joint_acceleration: float = Positive(5.0)
    settle_tolerance: float = Positive(1e-3)
    settle_timeout: float = Positive(2.0)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad limit."""
        CheckFields(self)


@dataclass(frozen=True)
class Trapezoid:
    """s(t) from 0 to 1 at rest at both ends with |ds/dt| <= speed, |d2s/dt2| <= accel
    (1/s, 1/s^2); a triangle when the cruise speed is never reached."""

    speed: float
    accel: float

    @property
    def ramp(self) -> float:
        """Duration of the acceleration phase (s)."""
        return min(self.speed / self.accel, math.sqrt(1.0 / self.accel))

    @property
    def duration(self) -> float:
        """Total duration (s)."""
        ramp = self.ramp
        peak = self.accel * ramp
        return 2 * ramp + (1.0 - peak * ramp) / peak

    def S(self, t: float) -> float:
        """The path parameter at time t (s) after the start."""
        ramp, total = self.ramp, self.duration
        peak = self.accel * ramp
        if t <= 0:
            return 0.0
        if t >= total:
            return 1.0
        if t < ramp:
            return 0.5 * self.accel * t * t
        if t <= total - ramp:
            return 0.5 * peak * ramp + peak * (t - ramp)
        return 1.0 - 0.5 * self.accel * (total - t) ** 2


@dataclass(frozen=True)
class JointMove:
    """Rest-to-rest segments through waypoints (K + 1, n) (rad), each with its profile."""

    waypoints: np.ndarray
    profiles: tuple[Trapezoid, ...]

    @property
    def duration(self) -> float:
        """Total duration (s)."""
        return float(sum(p.duration for p in self.profiles))

    @property
    def goal(self) -> np.ndarray:
        """The last waypoint (rad)."""
        return self.waypoints[-1]

    def Position(self, t: float) -> np.ndarray:
        """Joint positions (rad) at time t (s) after the start."""
        for k, profile in enumerate(self.profiles):
            if t < profile.duration:
                a, b = self.waypoints[k], self.waypoints[k + 1]
                return a + profile.S(t) * (b - a)
            t -= profile.duration
        return self.goal.copy()


def PlanJointMove(
    waypoints: list[np.ndarray], tool_points: list[np.ndarray], limits: MotionLimits
) -> JointMove:
    """The move through `waypoints` (rad), where the tool centre is at tool_points (m, any
    fixed frame). Segments without joint motion are dropped."""
    points, profiles = [np.asarray(waypoints[0], float)], []
    lengths = np.linalg.norm(np.diff(np.asarray(tool_points, float), axis=0), axis=1)
    for q, length in zip(waypoints[1:], lengths, strict=True):
        q = np.asarray(q, float)
        joint = float(np.max(np.abs(q - points[-1])))
        if joint < 1e-12:
            continue
        speed = limits.max_joint_speed / joint
        accel = limits.max_joint_acceleration / joint
        if length > 1e-12:
            speed = min(speed, limits.tool_speed / length)
            accel = min(accel, limits.tool_acceleration / length)
        points.append(q)
        profiles.append(Trapezoid(speed, accel))
    return JointMove(np.array(points), tuple(profiles))


@dataclass(frozen=True)
class SampledMove:
    """A move given by samples: times (s, from 0) and joint positions (samples x n, rad),
    linearly interpolated between samples (e.g. a planner's 2 ms commands)."""

    times: np.ndarray
    q: np.ndarray

    @property
    def duration(self) -> float:
        """Total duration (s)."""
        return float(self.times[-1])

    @property
    def goal(self) -> np.ndarray:
        """The last sample (rad)."""
        return self.q[-1]

    def Position(self, t: float) -> np.ndarray:
        """Joint positions (rad) at time t (s) after the start."""
        return np.array([np.interp(t, self.times, column) for column in self.q.T])


Move = JointMove | SampledMove
MovePlanner = Callable[[list[np.ndarray], list[np.ndarray]], Move]
"""Plans a move through joint waypoints (rad) given the tool centre at each (m)."""
