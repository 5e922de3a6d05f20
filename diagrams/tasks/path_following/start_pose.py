"""The path-following start pose and the random hoses the arm can trace from it.

`StartPosition` puts the tool centre O on a hose's first point, x_T along it, rolled by
the scenario's tool_roll_deg; `ReachableRandomPath` draws the seeded random hoses until
the arm can trace one with the tool held so (and, rolled, above the workspace floor).
Frames: world W, the arm's base B, gripper G, tool T. Units: m, rad.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.diagrams.tasks.path_following.scenario import PathFollowingScenario
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.path_following.hose_reach import CheckToolAboveFloor
from guidedarm.systems.path_following.path_follower_math import OrientationFromVector, ToolMount
from guidedarm.systems.path_following.tool_pose_ik_math import ToolPoseSolver
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.scene.hose_geometry import RandomSmoothPath


def StartPosition(
    solver: ToolPoseSolver,
    mount: ToolMount,
    centerline: np.ndarray,
    q_home: np.ndarray,
    roll: float = 0.0,
) -> np.ndarray:
    """Joints (rad) with the tool centre on the hose's first point (world frame), its x axis
    toward the point 4 rows on, rolled by `roll` (rad) about it: q_home itself when it
    holds the tool there already (e.g. a start pose in the scenario's initial_position),
    else solved from q_home (any rotation, any swing)."""
    ahead = centerline[min(4, len(centerline) - 1)]
    X_WT = RigidTransform(OrientationFromVector(ahead - centerline[0], roll), centerline[0])
    if solver.Reaches(mount.GripperPose(X_WT), q_home):
        return np.asarray(q_home, float)
    limits = solver.limits
    solver.limits = dataclasses.replace(
        limits, max_step_rotation_deg=180.0, max_swing=np.inf, shortfall_tolerance_deg=0.0
    )
    try:
        result = solver.Solve(mount.GripperPose(X_WT), q_home)
    finally:
        solver.limits = limits
    if not result.success:
        raise GuidedArmError(
            f"start pose out of reach: tool at {np.round(centerline[0], 3).tolist()} (m, world) "
            f"along the hose ({result.reason})"
        )
    return result.q


def ReachableRandomPath(
    scenario: PathFollowingScenario,
    seed: int,
    workspace: WorkspaceConfig,
    solver: ToolPoseSolver,
    mount: ToolMount,
    q_home: np.ndarray,
    tool_points_T: np.ndarray,
) -> np.ndarray:
    """The first random path (frame B) of the paper's sequence that the arm can trace with
    the tool on the centerline and along it, rolled by the scenario's tool_roll_deg (IK
    every 15 mm, no reconfiguration, no orientation shortfall) and with the tool
    (tool_points_T, its points in T) above the workspace floor: the generator's region is
    only an annulus in the workspace, the arm's reachable set with a downward tool is
    smaller. When every draw is refused, the last draw's reason is given (the floor's
    names the roll)."""
    roll = np.radians(scenario.tool_roll_deg)
    radius = scenario.station.hose.diameter / 2
    limits = solver.limits
    solver.limits = dataclasses.replace(limits, shortfall_tolerance_deg=0.0)
    why = "the arm cannot trace it"
    try:
        for attempt in range(20):
            path_B = RandomSmoothPath(
                seed * 1000 + attempt, scenario.random_path, workspace, radius
            )
            try:
                CheckToolAboveFloor(path_B, solver.X_WB, workspace, tool_points_T, roll)
            except ConfigurationError as error:
                why = str(error)
                continue
            # A rolled tool leans its gripper to one side of the hose, toward the arm
            # only when the hose runs one way round it: such a hose is tried both ways.
            for way in (path_B, path_B[::-1]) if roll else (path_B,):
                if _Traceable(solver, mount, solver.X_WB.multiply(way.T).T, q_home, roll):
                    return way
    finally:
        solver.limits = limits
    raise ConfigurationError(f"no reachable random path for seed {seed} ({why})")


def _Traceable(solver, mount, path: np.ndarray, q_home: np.ndarray, roll: float) -> bool:
    try:
        q = StartPosition(solver, mount, path, q_home, roll)
    except GuidedArmError:
        return False
    for a, b in zip(path[:-3:3], path[3::3], strict=True):
        X_WT = RigidTransform(OrientationFromVector(b - a, roll), a)
        result = solver.Solve(mount.GripperPose(X_WT), q)
        if not result.success:
            return False
        q = result.q
    return True
