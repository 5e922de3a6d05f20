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
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    ArmKinematics,
    DampedSolve,
    PoseError,
)


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
    `margin` (rad; the robust planner's joint_limit_margin), each the solution nearest the
    previous one (the first nearest q_start) that the solver finds, moved by whole turns
    towards it (NearestTurn).

    Each waypoint is solved from the previous solution, then from small perturbations of it
    (near a singularity the solver can stall at the guess itself), then from random
    configurations; every attempt is pulled towards the previous solution by its cost, so a
    restart does not jump to another branch of the arm when a near one exists.
    Raises ConfigurationError naming the first waypoint that has no solution.
    """
    plant, instance = kinematics.plant, kinematics.instance
    context = plant.CreateDefaultContext()
    q_lower, q_upper = kinematics.PositionLimits()
    limits = (q_lower + margin, q_upper - margin)
    lower, upper = np.maximum(limits[0], -np.pi), np.minimum(limits[1], np.pi)
    rng = np.random.default_rng(0)
    solutions = []
    q_previous = np.asarray(q_start, float)
    for i, p in enumerate(np.atleast_2d(waypoints)):
        X_BT = WaypointPose(p)
        near = [q_previous + rng.normal(0.0, 0.05 * k, 6) for k in (1, 2, 4)]
        far = [rng.uniform(lower, upper) for _ in range(attempts - 1)]
        for guess in [q_previous, *near, *far]:
            q = _Solve(kinematics, context, X_BT, guess, q_previous, tolerance, limits)
            if q is not None:
                break
        else:
            raise ConfigurationError(
                f"waypoint {i + 1} {np.round(p, 4).tolist()} is out of reach of "
                f"{plant.GetModelInstanceName(instance)} (no joint solution within its limits)"
            )
        q = NearestTurn(q, q_previous, limits)
        solutions.append(q)
        q_previous = q
    return np.array(solutions)


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
    return _Polish(
        kinematics,
        X_BT,
        plant.GetPositionsFromArray(instance, result.GetSolution(ik.q())),
        limits,
    )


def _Polish(
    kinematics: ArmKinematics,
    X_BT: RigidTransform,
    q: np.ndarray,
    limits: tuple[np.ndarray, np.ndarray],
) -> np.ndarray:
    """q moved onto the pose X_BT by Newton steps on [position; rotation vector] error.

    The solver's orientation constraint bounds trace(R), so an accepted solution can be
    off by up to about 1e-3 rad; the robust planner converges onto these joints near
    singularities, so they must hold the pose itself. Steps that would leave the joint
    limits are not taken (the solver's solution is kept)."""
    lower, upper = limits
    x_target, R_target = X_BT.translation(), X_BT.rotation().matrix()
    polished = q.copy()
    for _ in range(20):
        kin = kinematics.Evaluate(polished, np.zeros(6), analytic=False)
        e = PoseError(kin, x_target, R_target)
        if np.max(np.abs(e)) < 1e-12:
            break
        step = DampedSolve(kin.J, e, 1e-12)
        if not np.all(np.isfinite(step)):
            return q
        polished = polished - step
    if np.any(polished < lower - 1e-9) or np.any(polished > upper + 1e-9):
        return q
    return polished
