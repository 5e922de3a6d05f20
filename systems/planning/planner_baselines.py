"""Baselines for the waypoint planner: a UR-controller-like movej, Drake's Toppra and Ruckig.

All move through the same joint waypoints (the IK solutions of the TCP waypoints) under
symmetric joint velocity and acceleration limits, and are sampled at the planner period.

Ruckig (community version, offline): jerk-limited time-optimal state-to-state segments
between consecutive joint waypoints, each ending at the next waypoint with a via velocity
and zero acceleration. Its waypoint mode (intermediate positions) is the pro version's
remote service and is not used. The via velocities are Toppra's at the waypoints: the
time-optimal velocities along the spline through them under the same velocity and
acceleration limits, so Ruckig passes each waypoint as fast as Toppra does.

movej (UR e-Series manual, "MoveJ" with "blend radius"): each segment moves all joints
synchronously along a straight line in joint space, timed by a trapezoidal velocity profile
of the leading axis (the one with the largest move relative to its limits). With a blend
radius r the next segment starts as soon as the TCP comes within r of the waypoint, and
the two segments' displacements add up; that keeps the velocity continuous but lets the
accelerations of both segments add in the blend, as in the paper's experiment 1.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.multibody.plant import MultibodyPlant
from pydrake.trajectories import PiecewisePolynomial, Trajectory
from ruckig import InputParameter, Result, Ruckig
from ruckig import Trajectory as RuckigTrajectory

from guidedarm.systems.errors import GuidedArmError


@dataclass
class JointTrajectory:
    """Samples at a fixed period: times (s), q (rad), qd (rad/s), qdd (rad/s^2)."""

    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


def TrapezoidProfile(distance: float, v_max: float, a_max: float) -> tuple[float, Callable]:
    """Duration (s) and lambda(t) -> (s, s', s'') of a rest-to-rest trapezoidal profile over
    the normalised distance 0..1 of a move of `distance` (rad) under v_max, a_max."""
    if distance <= 0:
        return 0.0, lambda t: (np.ones_like(t), np.zeros_like(t), np.zeros_like(t))
    v_peak = min(v_max, np.sqrt(distance * a_max))
    t_ramp = v_peak / a_max
    duration = distance / v_peak + t_ramp

    def profile(t: np.ndarray):
        t = np.clip(t, 0.0, duration)
        back = duration - t
        rising, falling = t < t_ramp, back < t_ramp
        position = np.where(
            rising,
            0.5 * a_max * t**2,
            np.where(falling, distance - 0.5 * a_max * back**2, v_peak * (t - 0.5 * t_ramp)),
        )
        velocity = np.where(rising, a_max * t, np.where(falling, a_max * back, v_peak))
        acceleration = np.where(rising, a_max, np.where(falling, -a_max, 0.0))
        acceleration = np.where((t <= 0) | (t >= duration), 0.0, acceleration)
        return position / distance, velocity / distance, acceleration / distance

    return duration, profile


def MoveJ(
    joint_waypoints: np.ndarray,
    tcp_position: Callable[[np.ndarray], np.ndarray],
    v_max: np.ndarray,
    a_max: np.ndarray,
    blend_radius: float,
    period: float,
) -> JointTrajectory:
    """movej through joint_waypoints (rows; the first is the start) with blending.

    tcp_position(q) -> TCP position (m) decides when the TCP is within blend_radius of a
    waypoint; no blend at the last one.
    """
    moves = np.diff(joint_waypoints, axis=0)
    profiles, starts = [], []
    t_start = 0.0
    for i, move in enumerate(moves):
        ratio = np.abs(move) / v_max  # the leading axis needs the longest time at v_max
        lead = int(np.argmax(ratio))
        duration, profile = TrapezoidProfile(abs(move[lead]), v_max[lead], a_max[lead])
        profiles.append((duration, profile))
        starts.append(t_start)
        if i + 1 < len(moves):
            t_start += _BlendStart(
                joint_waypoints[i], move, duration, profile, tcp_position, blend_radius, period
            )
    t_end = starts[-1] + profiles[-1][0]
    times = np.arange(0.0, t_end + period / 2, period)
    q = np.tile(joint_waypoints[0], (times.size, 1)).astype(float)
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for move, start, (_, profile) in zip(moves, starts, profiles, strict=True):
        s, ds, dds = profile(times - start)
        q += np.outer(s, move)
        qd += np.outer(ds, move)
        qdd += np.outer(dds, move)
    return JointTrajectory(times, q, qd, qdd)


def _BlendStart(q_from, move, duration, profile, tcp_position, radius, period) -> float:
    """Time into a segment at which the TCP first comes within `radius` of its end."""
    target = tcp_position(q_from + move)
    for t in np.arange(0.0, duration, period):
        s = float(profile(np.array(t))[0])
        if np.linalg.norm(tcp_position(q_from + s * move) - target) < radius:
            return t
    return duration


def ToppraThroughWaypoints(
    plant: MultibodyPlant,
    joint_waypoints: np.ndarray,
    v_max: np.ndarray,
    a_max: np.ndarray,
    period: float,
) -> tuple[JointTrajectory, np.ndarray]:
    """Time-optimal parameterisation (Drake's Toppra) of a C2 cubic spline through the
    joint waypoints (knots at the cumulative joint-space distance, at rest at both ends).
    Returns the sampled trajectory and the joint velocities at the waypoints (rad/s, one row
    per waypoint).

    `plant` must have exactly the arm's joints as positions.
    """
    if plant.num_positions() != joint_waypoints.shape[1]:
        raise GuidedArmError("Toppra baseline: the plant must hold only the arm's joints")
    distances = np.linalg.norm(np.diff(joint_waypoints, axis=0), axis=1)
    knots = np.concatenate([[0.0], np.cumsum(np.maximum(distances, 1e-6))])
    zero = np.zeros(joint_waypoints.shape[1])
    path = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        knots, joint_waypoints.T, zero, zero
    )
    toppra = Toppra(
        path,
        plant,
        Toppra.CalcGridPoints(path, CalcGridPointsOptions(max_seg_length=0.01, min_points=1000)),
    )
    toppra.AddJointVelocityLimit(-v_max, v_max)
    toppra.AddJointAccelerationLimit(-a_max, a_max)
    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.CRITICAL)  # a failure is reported once, by the error below
    try:
        s_trajectory = toppra.SolvePathParameterization()
    finally:
        drake_log.setLevel(level)
    if s_trajectory is None:
        raise GuidedArmError("Toppra found no parameterisation under the limits")
    times = np.arange(0.0, s_trajectory.end_time() + period / 2, period)
    times[-1] = min(times[-1], s_trajectory.end_time())
    s = s_trajectory.vector_values(times)[0]
    ds = np.array([s_trajectory.EvalDerivative(t, 1)[0, 0] for t in times])
    dds = np.array([s_trajectory.EvalDerivative(t, 2)[0, 0] for t in times])
    dpath = path.MakeDerivative(1)
    ddpath = path.MakeDerivative(2)
    q = path.vector_values(s).T
    first = dpath.vector_values(s).T
    second = ddpath.vector_values(s).T
    qd = first * ds[:, None]
    qdd = second * ds[:, None] ** 2 + first * dds[:, None]
    via = np.array(
        [dpath.value(k)[:, 0] * s_trajectory.EvalDerivative(_TimeAt(s_trajectory, k), 1)[0, 0]
         for k in knots]
    )  # fmt: skip
    return JointTrajectory(times, q, qd, qdd), via


def _TimeAt(s_trajectory: Trajectory, s_value: float) -> float:
    """The time at which the monotone path parameter s(t) reaches s_value (bisection)."""
    lo, hi = s_trajectory.start_time(), s_trajectory.end_time()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if s_trajectory.value(mid)[0, 0] < s_value:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def RuckigThroughWaypoints(
    joint_waypoints: np.ndarray,
    via_velocities: np.ndarray,
    v_max: np.ndarray,
    a_max: np.ndarray,
    j_max: np.ndarray,
    period: float,
) -> JointTrajectory:
    """Ruckig's jerk-limited time-optimal segments from rest at the first joint waypoint
    through the others (rad) to rest at the last, passing waypoint k with velocity
    via_velocities[k] (rad/s; the first and last rows are ignored: rest) and zero
    acceleration, under |qd| <= v_max, |qdd| <= a_max, |jerk| <= j_max; sampled at `period`.
    Via velocities are clipped to the velocity limits (Toppra's grid may pass them by a
    fraction of a percent)."""
    n = joint_waypoints.shape[1]
    via_velocities = np.clip(via_velocities, -v_max, v_max)
    generator = Ruckig(n)
    segments = []
    for k in range(len(joint_waypoints) - 1):
        last = k + 2 == len(joint_waypoints)
        parameters = InputParameter(n)
        parameters.current_position = joint_waypoints[k]
        parameters.current_velocity = np.zeros(n) if k == 0 else via_velocities[k]
        parameters.current_acceleration = np.zeros(n)
        parameters.target_position = joint_waypoints[k + 1]
        parameters.target_velocity = np.zeros(n) if last else via_velocities[k + 1]
        parameters.target_acceleration = np.zeros(n)
        parameters.max_velocity = v_max
        parameters.max_acceleration = a_max
        parameters.max_jerk = j_max
        segment = RuckigTrajectory(n)
        result = generator.calculate(parameters, segment)
        if result not in (Result.Working, Result.Finished):
            raise GuidedArmError(f"Ruckig found no segment {k + 1} ({result})")
        segments.append(segment)
    ends = np.cumsum([segment.duration for segment in segments])
    times = np.arange(0.0, ends[-1] + period / 2, period)
    times[-1] = min(times[-1], ends[-1])
    samples = np.zeros((3, times.size, n))
    for i, t in enumerate(times):
        k = min(int(np.searchsorted(ends, t)), len(segments) - 1)
        start = ends[k - 1] if k else 0.0
        samples[:, i] = segments[k].at_time(t - start)
    return JointTrajectory(times, *samples)
