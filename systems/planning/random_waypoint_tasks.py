"""Seeded random reachable waypoint tasks for the acceleration-level planner.

Each task starts at a configuration away from the joint limits and has three waypoints, each
made by forward kinematics of a configuration near the previous one (so every waypoint is
reachable), 0.05-0.25 m and at most 40 deg from the previous TCP pose. Tasks come in three
kinds, in turn: `regular`; `near_singular`, whose start has the smallest singular value of
the Jacobian J_g between 0.01 and 0.03; `steep`, with a waypoint at a Z-Y-X pitch of 70-85 deg
(near the Euler-angle singularity of the paper's orientation error). Every waypoint keeps
|pitch| <= 85 deg and a configuration with smallest singular value >= 0.01. The kinematics
know no cell: a caller that does passes a `clear` predicate, and starts and waypoint
configurations that collide are drawn again.

Units: m, rad. Waypoint rows [x, y, z, roll, pitch, yaw] of the TCP T in the base frame B.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.systems.planning.acceleration_planner_kinematics import (
    ArmKinematics,
    RotationError,
)

KINDS = ("regular", "near_singular", "steep")
# Kinds made only on request (MakeRandomWaypointTasks's `kind`), so the seeded mixed set of
# KINDS stays as it is: `near_limit`, a start with one or two joints 0.02-0.15 rad from a
# position limit; `large`, moves of 0.2-0.5 m turning up to 90 deg.
EXTRA_KINDS = ("near_limit", "large")
NEAR_LIMIT_RAD = (0.02, 0.15)
WAYPOINT_COUNT = 3
STEP_M = (0.05, 0.25)
LARGE_STEP_M = (0.2, 0.5)
MAX_TURN_RAD = np.radians(40.0)
LARGE_TURN_RAD = np.radians(90.0)
MAX_PITCH_RAD = np.radians(85.0)
STEEP_PITCH_RAD = np.radians(70.0)
SINGULAR_SIGMA = (0.01, 0.03)
MIN_SIGMA = 0.01
LIMIT_MARGIN = 0.15  # fraction of each joint's range kept free at both ends


@dataclass
class RandomWaypointTask:
    """One task: start q0 (rad), waypoints (rows, m and rad), the configurations they were
    made from (rad), its kind, and the smallest singular value of J_g at q0."""

    q0: np.ndarray
    waypoints: np.ndarray
    joint_waypoints: np.ndarray
    kind: str
    start_sigma: float


def MakeRandomWaypointTasks(
    kinematics: ArmKinematics,
    count: int,
    seed: int = 0,
    kind: str | None = None,
    clear: Callable[[np.ndarray], bool] | None = None,
) -> list[RandomWaypointTask]:
    """`count` tasks for the arm of `kinematics`, the same for the same seed: the KINDS in
    turn, or all of one `kind` (of KINDS or EXTRA_KINDS). With `clear` (joint positions,
    rad -> whether the arm is clear of its cell, e.g. CellCollisions), every start and
    waypoint configuration is drawn again until it is clear; without it the tasks are those
    of the same seed as ever."""
    rng = np.random.default_rng(seed)
    lower, upper = _JointRange(kinematics)
    kinds = KINDS if kind is None else (kind,)
    clear = clear or _Anywhere
    return [
        _MakeTask(kinematics, kinds[k % len(kinds)], lower, upper, rng, clear) for k in range(count)
    ]


def _Anywhere(q: np.ndarray) -> bool:
    return True


def _JointRange(kinematics: ArmKinematics) -> tuple[np.ndarray, np.ndarray]:
    """The joint ranges (rad) the tasks use: the limits (at most +-pi) shrunk by the margin."""
    lower, upper = kinematics.JointLimits()
    margin = LIMIT_MARGIN * (upper - lower)
    return lower + margin, upper - margin


def _MakeTask(kinematics, kind, lower, upper, rng, clear) -> RandomWaypointTask:
    while True:
        q0 = rng.uniform(lower, upper)
        sigma = kinematics.MinSingularValue(q0)
        pitch = abs(kinematics.Position(q0)[4])
        if kind == "near_singular":
            q0 = _NearSingular(kinematics, q0, lower, upper, rng)
            if q0 is None:
                continue
            sigma = kinematics.MinSingularValue(q0)
        elif sigma < SINGULAR_SIGMA[1] or (kind == "steep" and pitch < STEEP_PITCH_RAD - 0.1):
            continue
        if kind == "near_limit":
            q0 = _NearLimit(kinematics, q0, rng)
            if kinematics.MinSingularValue(q0) < SINGULAR_SIGMA[1]:
                continue
        if abs(kinematics.Position(q0)[4]) > MAX_PITCH_RAD or not clear(q0):
            continue
        box = (lower, upper)
        if kind == "near_limit":  # waypoints anywhere within the limits, as the start
            q_lower, q_upper = kinematics.PositionLimits()
            box = (q_lower + NEAR_LIMIT_RAD[0], q_upper - NEAR_LIMIT_RAD[0])
        joints = _Waypoints(kinematics, q0, *box, rng, clear, large=kind == "large")
        if joints is None:
            continue
        waypoints = np.array([kinematics.Position(q) for q in joints])
        if kind == "steep" and np.max(np.abs(waypoints[:, 4])) < STEEP_PITCH_RAD:
            continue
        return RandomWaypointTask(q0, waypoints, joints, kind, sigma)


def _NearSingular(kinematics, q, lower, upper, rng) -> np.ndarray | None:
    """q with one random joint moved so that the smallest singular value of J_g is a random
    value in SINGULAR_SIGMA (bisection along the joint), or None if that joint cannot."""
    target = rng.uniform(*SINGULAR_SIGMA)
    k = int(rng.integers(6))
    values = np.linspace(lower[k], upper[k], 121)
    sigmas = []
    for value in values:
        q_k = q.copy()
        q_k[k] = value
        sigmas.append(kinematics.MinSingularValue(q_k) - target)
    crossings = np.flatnonzero(np.sign(sigmas[:-1]) != np.sign(sigmas[1:]))
    if crossings.size == 0:
        return None
    i = int(rng.choice(crossings))
    lo, hi = values[i], values[i + 1]
    sign_lo = np.sign(sigmas[i])
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        q_k = q.copy()
        q_k[k] = mid
        if np.sign(kinematics.MinSingularValue(q_k) - target) == sign_lo:
            lo = mid
        else:
            hi = mid
    q = q.copy()
    q[k] = 0.5 * (lo + hi)
    return q


def _NearLimit(kinematics, q, rng) -> np.ndarray:
    """q with one or two random joints moved 0.02-0.15 rad (NEAR_LIMIT_RAD) inside one of
    their position limits (the plant's, e.g. +-2 pi on most UR10e joints)."""
    q_lower, q_upper = kinematics.PositionLimits()
    q = q.copy()
    for k in rng.choice(6, size=int(rng.integers(1, 3)), replace=False):
        gap = rng.uniform(*NEAR_LIMIT_RAD)
        q[k] = q_lower[k] + gap if rng.random() < 0.5 else q_upper[k] - gap
    return q


def _Waypoints(
    kinematics, q0, lower, upper, rng, clear, attempts: int = 400, large: bool = False
) -> np.ndarray | None:
    """WAYPOINT_COUNT configurations, each near the previous one and `clear`, whose TCP
    poses keep the step and turn bounds (the large ones with `large`); None if none is
    found within the attempts."""
    joints = []
    q_previous = q0
    reach, steps, turn = (1.5, LARGE_STEP_M, LARGE_TURN_RAD) if large else (0.6, STEP_M, None)
    for _ in range(WAYPOINT_COUNT):
        for _ in range(attempts):
            q = np.clip(q_previous + rng.uniform(-reach, reach, 6), lower, upper)
            if _Acceptable(kinematics, q_previous, q, steps, turn or MAX_TURN_RAD) and clear(q):
                break
        else:
            return None
        joints.append(q)
        q_previous = q
    return np.array(joints)


def _Acceptable(
    kinematics, q_previous: np.ndarray, q: np.ndarray, steps=STEP_M, max_turn=MAX_TURN_RAD
) -> bool:
    p0, p1 = kinematics.Position(q_previous), kinematics.Position(q)
    step = float(np.linalg.norm(p1[:3] - p0[:3]))
    R0 = RotationMatrix(RollPitchYaw(p0[3:])).matrix()
    R1 = RotationMatrix(RollPitchYaw(p1[3:])).matrix()
    turn = float(np.linalg.norm(RotationError(R1, R0)))
    return (
        steps[0] <= step <= steps[1]
        and turn <= max_turn
        and abs(p1[4]) <= MAX_PITCH_RAD
        and kinematics.MinSingularValue(q) >= MIN_SIGMA
    )
