"""Joint solutions of TCP waypoints: the planner's reachability check before any motion.

A waypoint out of the arm's reach would only show up as a run that never ends (or, in the
paper's law, a misleading case (c)). Solving the IK of every waypoint first (each from the
previous solution, so they lie on one branch) refuses such a task at once; the solutions
are the targets of the robust mode's joint-space blend near singularities and the joint
waypoints of the baselines the planner is compared with.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import ArmKinematics, PoseError

_POLISH_STEPS = 30  # Newton converges in a few; near a singularity it is linear


def WaypointPose(p: np.ndarray) -> RigidTransform:
    """X_BT of a waypoint row [x, y, z, roll, pitch, yaw] (m, rad; Z-Y-X Euler angles)."""
    return RigidTransform(RollPitchYaw(p[3:]), p[:3])


def SolveWaypointIk(
    kinematics: ArmKinematics,
    waypoints: np.ndarray,
    q_start: np.ndarray,
    tolerance: float = 1e-6,
    attempts: int = 24,
    margin: float = 0.0,
) -> np.ndarray:
    """Joint positions (rad), one row per waypoint, within the plant's joint limits less
    `margin` (rad; the robust planner's joint_limit_margin), each holding its waypoint's pose
    to `tolerance` (m and rad) and the solution nearest the previous one (the first nearest
    q_start) that the solver finds, moved by whole turns towards it (NearestTurn).

    Each waypoint is solved from the previous solution, then from small perturbations of it
    (near a singularity the solver can stall at the guess itself); the first exact solution
    of these is taken. Failing that (e.g. the near branch holds the pose only with a joint
    past its limit), it is solved from `attempts` - 1 random configurations and the exact
    solution nearest the previous one is taken. Every attempt is pulled towards the previous
    solution by its cost, so a restart does not jump to another branch of the arm when a
    near one exists. Raises ConfigurationError naming the first waypoint that has no exact
    solution within the limits, and by how much the nearest inexact one misses it.
    """
    context = kinematics.plant.CreateDefaultContext()
    q_lower, q_upper = kinematics.PositionLimits()
    limits = (q_lower + margin, q_upper - margin)
    lower, upper = np.maximum(limits[0], -np.pi), np.minimum(limits[1], np.pi)
    rng = np.random.default_rng(0)
    solutions = []
    q_previous = np.asarray(q_start, float)
    for i, p in enumerate(np.atleast_2d(waypoints)):
        solve = _WaypointSolver(kinematics, context, WaypointPose(p), q_previous, tolerance, limits)
        near = [q_previous + rng.normal(0.0, 0.05 * k, 6) for k in (1, 2, 4)]
        far = [rng.uniform(lower, upper) for _ in range(attempts - 1)]
        q = next((q for q in map(solve, [q_previous, *near]) if q is not None), None)
        if q is None:
            exact = [q for q in map(solve, far) if q is not None]
            if not exact:
                raise ConfigurationError(_OutOfReach(kinematics, i, p, solve.misses, margin))
            q = min(exact, key=lambda q: float(np.linalg.norm(q - q_previous)))
        solutions.append(q)
        q_previous = q
    return np.array(solutions)


def WaypointIkBranches(
    kinematics: ArmKinematics,
    waypoints: np.ndarray,
    joint_waypoints: np.ndarray,
    q_start: np.ndarray,
    index: int,
    margin: float = 0.0,
    guesses: int = 40,
) -> list[np.ndarray]:
    """Other joint solutions of the waypoints (rad, one row per waypoint, like
    SolveWaypointIk's `joint_waypoints` from q_start) that differ from waypoint `index`
    (0-based) on: the rows before it kept, waypoint `index` on another exact solution
    (another IK branch: elbow, shoulder or wrist flipped, or a joint a turn away) and each
    later waypoint the solution nearest the one before; nearest first (joint distance of
    waypoint `index` from the configuration before it). The solutions are those found from
    `guesses` seeded random configurations within the limits less `margin` (rad); a
    branch on which a later waypoint has no exact solution is left out."""
    waypoints = np.atleast_2d(waypoints)
    q_lower, q_upper = kinematics.PositionLimits()
    limits = (q_lower + margin, q_upper - margin)
    lower, upper = np.maximum(limits[0], -np.pi), np.minimum(limits[1], np.pi)
    q_before = np.asarray(q_start, float) if index == 0 else joint_waypoints[index - 1]
    context = kinematics.plant.CreateDefaultContext()
    solve = _WaypointSolver(
        kinematics, context, WaypointPose(waypoints[index]), q_before, 1e-6, limits
    )
    rng = np.random.default_rng(0)
    found = [joint_waypoints[index]]
    for _ in range(guesses):
        q = solve(rng.uniform(lower, upper))
        if q is not None and all(np.linalg.norm(q - other) > 1e-3 for other in found):
            found.append(q)
    branches = []
    for q in sorted(found[1:], key=lambda q: float(np.linalg.norm(q - q_before))):
        try:
            later = SolveWaypointIk(kinematics, waypoints[index + 1 :], q, margin=margin)
        except ConfigurationError:
            continue
        branches.append(np.vstack([joint_waypoints[:index], q, later.reshape(-1, 6)]))
    return branches


class _WaypointSolver:
    """Called with a guess: the exact joint solution (rad) of one waypoint's pose X_BT the
    solver finds from it, polished and moved by whole turns towards q_near, or None; the
    inexact ones' misses (m or rad) are kept in `misses` for the refusal."""

    def __init__(self, kinematics, context, X_BT, q_near, tolerance, limits) -> None:
        self._kinematics, self._context, self._X_BT = kinematics, context, X_BT
        self._q_near, self._tolerance, self._limits = q_near, tolerance, limits
        self.misses: list[float] = []

    def __call__(self, guess: np.ndarray) -> np.ndarray | None:
        kinematics, X_BT, limits = self._kinematics, self._X_BT, self._limits
        q = _Solve(kinematics, self._context, X_BT, guess, self._q_near, self._tolerance, limits)
        if q is None:
            return None
        q, miss = _Polish(kinematics, X_BT, q, limits)
        if miss > self._tolerance:
            self.misses.append(miss)
            return None
        return NearestTurn(q, self._q_near, self._limits)


def _OutOfReach(
    kinematics: ArmKinematics, i: int, p: np.ndarray, misses: list[float], margin: float
) -> str:
    """The one-line refusal of waypoint i (0-based) with row p."""
    name = kinematics.plant.GetModelInstanceName(kinematics.instance)
    cause = f"no joint solution within its limits less {margin} rad"
    if misses:
        cause += f"; the nearest misses the pose by {min(misses):.2g} m or rad"
    return f"waypoint {i + 1} {np.round(p, 4).tolist()} is out of reach of {name} ({cause})"


def NearestTurn(
    q: np.ndarray, q_near: np.ndarray, limits: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """q with each joint moved by whole turns (2 pi, the same pose for a revolute joint)
    as near to q_near as the limits allow: on joints that can turn more than once (the
    UR10e's +-2 pi) the solver may return a solution a turn away from the nearest one."""
    turns = np.round((q_near - q) / (2 * np.pi))
    nearest = q + 2 * np.pi * turns
    inside = (nearest >= limits[0]) & (nearest <= limits[1])
    return np.where(inside, nearest, q)


def _Solve(
    kinematics: ArmKinematics,
    context,
    X_BT: RigidTransform,
    guess: np.ndarray,
    nearest: np.ndarray,
    tolerance: float,
    limits: tuple[np.ndarray, np.ndarray],
) -> np.ndarray | None:
    plant, instance = kinematics.plant, kinematics.instance
    plant.SetPositions(context, instance, guess)
    ik = InverseKinematics(plant, context, with_joint_limits=True)
    p = X_BT.translation()
    ik.AddPositionConstraint(
        kinematics.tool_frame, np.zeros(3), kinematics.base_frame, p - tolerance, p + tolerance
    )
    ik.AddOrientationConstraint(
        kinematics.base_frame, X_BT.rotation(), kinematics.tool_frame, RotationMatrix(), tolerance
    )
    prog = ik.get_mutable_prog()
    q_full = plant.GetPositions(context)
    mask = np.zeros(plant.num_positions())
    plant.SetPositionsInArray(instance, np.ones(6), mask)
    arm = mask > 0
    if (~arm).any():  # the rest of the scene stays where it is
        prog.AddBoundingBoxConstraint(q_full[~arm], q_full[~arm], ik.q()[~arm])
    prog.AddQuadraticErrorCost(np.eye(int(arm.sum())) * 1e-3, nearest, ik.q()[arm])
    prog.AddBoundingBoxConstraint(limits[0], limits[1], ik.q()[arm])
    result = Solve(prog, q_full)
    if not result.is_success():
        return None
    return plant.GetPositionsFromArray(instance, result.GetSolution(ik.q()))


def _Polish(
    kinematics: ArmKinematics,
    X_BT: RigidTransform,
    q: np.ndarray,
    limits: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, float]:
    """q moved onto the pose X_BT by Newton steps on the [position; rotation vector] error,
    never leaving the limits, and what it still misses: (q (rad), max |error| (m, rad)).

    The solver's orientation constraint bounds trace(R), so an accepted solution can be
    off by up to about 1e-3 rad; the robust planner converges onto these joints near
    singularities and once handed over to joint space, so they must hold the pose itself.
    A step that would take joints past a limit takes them to it and solves the rest of
    the error with the other joints (a bounded Newton step); where the pose needs a joint
    past its limit the miss stays above zero and the caller refuses the solution."""
    lower, upper = limits
    x_target, R_target = X_BT.translation(), X_BT.rotation().matrix()
    q = np.clip(q, lower, upper)
    for _ in range(_POLISH_STEPS):
        kin = kinematics.Evaluate(q, np.zeros(6), analytic=False)
        e = PoseError(kin, x_target, R_target)
        if np.max(np.abs(e)) < 1e-12:
            break
        q = np.clip(q - _BoundedStep(kin.J, e, q, limits), lower, upper)
    kin = kinematics.Evaluate(q, np.zeros(6), analytic=False)
    return q, float(np.max(np.abs(PoseError(kin, x_target, R_target))))


def _BoundedStep(
    J: np.ndarray, e: np.ndarray, q: np.ndarray, limits: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """The Newton step dq (rad) with J dq = e in least squares, joints that q - dq would
    take past a limit held at it (one at a time, the furthest first)."""
    lower, upper = limits
    step = np.zeros(q.size)
    free = np.ones(q.size, bool)
    while free.any():
        rhs = e - J[:, ~free] @ step[~free]
        step[free] = np.linalg.lstsq(J[:, free], rhs, rcond=None)[0]
        q_next = q - step
        past = np.where(free, np.maximum(lower - q_next, q_next - upper), 0.0)
        if past.max() <= 0.0:
            break
        j = int(np.argmax(past))
        step[j] = q[j] - np.clip(q_next[j], lower[j], upper[j])
        free[j] = False
    return step
