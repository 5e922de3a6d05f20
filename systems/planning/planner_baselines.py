"""Baselines for the waypoint planner: a UR-controller-like movej and Drake's Toppra.

Both move through the same joint waypoints (the IK solutions of the TCP waypoints) under
symmetric joint velocity and acceleration limits, and are sampled at the planner period.

movej (UR e-Series manual, "MoveJ" with "blend radius"): each segment moves all joints
synchronously along a straight line in joint space, timed by a trapezoidal velocity profile
of the leading axis (the one with the largest move relative to its limits). With a blend
radius r the next segment starts as soon as the TCP comes within r of the waypoint, and
the two segments' displacements add up; that keeps the velocity continuous but lets the
accelerations of both segments add in the blend, as in the seed's experiment 1.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.multibody.plant import MultibodyPlant
from pydrake.trajectories import PiecewisePolynomial

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
) -> JointTrajectory:
    """Time-optimal parameterisation (Drake's Toppra) of a C2 cubic spline through the
    joint waypoints (knots at the cumulative joint-space distance, at rest at both ends).

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
    s_trajectory = toppra.SolvePathParameterization()
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
    return JointTrajectory(times, q, qd, qdd)
