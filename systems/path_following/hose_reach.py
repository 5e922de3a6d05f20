"""Whether an arm can follow a hose at all, checked before the run: its reach and the
tool's clearance from the workspace walls.

Reach: every revolute joint keeps its own origin fixed, so the distance between the origin
of joint k and that of joint k + 1 is a constant of link k, and the tool's centre O lies at
most their sum (plus the last link's distance to O) from the shoulder S, the origin of
the arm's second joint, which the first joint turns about its own axis. A hose point
farther than that from S cannot be reached in any configuration. The bound is exact for an
arm that can stretch straight; the tool's orientation during following makes the true
reach somewhat smaller, which the IK reports during the run.

Clearance: the IK and the servo keep the origin of every body the arm moves inside the
workspace box, and the tool's bodies sit up to `ToolClearance` from O in any orientation:
a hose point nearer a wall than that would make the tool cross it where the hose runs.
The floor (the workspace's z lower wall, over the table) is checked with the tool as the
followers hold it instead: x_T along the hose, rolled by the scenario's tool_roll_deg
(OrientationFromVector), every point of the tool (`ToolPoints`: its bodies' origins, which
the IK keeps inside the walls, and the corners of its collision shapes' bounding boxes)
above the wall. That is what lets a rolled tool follow a hose lying on the table, and
what refuses a roll that would put the tool under it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder, Ellipsoid, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex
from pydrake.systems.framework import Context

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.path_follower_math import OrientationFromVector
from guidedarm.systems.path_following.workspace import WorkspaceConfig


@dataclass(frozen=True)
class ArmReach:
    """p_WS: the shoulder S (m, world); reach: the largest distance of the tool centre from
    it (m)."""

    p_WS: np.ndarray
    reach: float


def CalcArmReach(
    plant: MultibodyPlant, arm: ModelInstanceIndex, frame: Frame, p_FO: np.ndarray
) -> ArmReach:
    """The reach of the point O (p_FO in `frame`, e.g. the ToF tool's centre held by the
    gripper frame) of the arm `arm` of a finalized plant (see the module docstring)."""
    context = plant.CreateDefaultContext()
    joints = [
        plant.get_joint(j) for j in plant.GetJointIndices(arm) if plant.get_joint(j).num_positions()
    ]
    origins = [j.frame_on_child().CalcPoseInWorld(context).translation() for j in joints[1:]]
    origins.append(frame.CalcPoseInWorld(context).multiply(np.asarray(p_FO, float)))
    lengths = np.linalg.norm(np.diff(np.array(origins), axis=0), axis=1)
    return ArmReach(origins[0], float(lengths.sum()))


def ToolClearance(plant: MultibodyPlant, tool_frame: Frame) -> float:
    """The largest distance (m) of the origin of a body of the tool's model instance from
    the tool frame's origin: how near a wall the tool's centre may come in any orientation
    with every body of the tool inside."""
    context = plant.CreateDefaultContext()
    X_WT = tool_frame.CalcPoseInWorld(context)
    bodies = plant.GetBodyIndices(tool_frame.model_instance())
    return max(
        float(
            np.linalg.norm(
                plant.EvalBodyPoseInWorld(context, plant.get_body(b)).translation()
                - X_WT.translation()
            )
        )
        for b in bodies
    )


def ToolPoints(plant: MultibodyPlant, context: Context, tool_frame: Frame) -> np.ndarray:
    """(N, 3) points of the tool in its frame T (m): the origin of every body of the tool
    frame's model instance and the corners of the box bounding each of their collision
    shapes (boxes exactly; cylinders, capsules, spheres and ellipsoids by their bounding
    boxes; other shapes by their origin). `context`: a context of `plant` connected to its
    SceneGraph (the shapes come from its inspector)."""
    inspector = plant.get_geometry_query_input_port().Eval(context).inspector()
    points = []
    for index in plant.GetBodyIndices(tool_frame.model_instance()):
        body = plant.get_body(index)
        X_TB = plant.CalcRelativeTransform(context, tool_frame, body.body_frame())
        points.append(X_TB.translation())
        for geometry in plant.GetCollisionGeometriesForBody(body):
            half = _HalfExtents(inspector.GetShape(geometry))
            corners = np.array(np.meshgrid(*[(-h, h) for h in half])).reshape(3, -1).T
            X_TG = X_TB @ inspector.GetPoseInFrame(geometry)
            points.extend(X_TG.multiply(corners.T).T)
    return np.array(points)


def _HalfExtents(shape) -> np.ndarray:
    """Half sizes (m) of the box bounding `shape` in its own frame (zeros if unknown)."""
    if isinstance(shape, Box):
        return np.array([shape.width(), shape.depth(), shape.height()]) / 2
    if isinstance(shape, Cylinder):
        return np.array([shape.radius(), shape.radius(), shape.length() / 2])
    if isinstance(shape, Capsule):
        r = shape.radius()
        return np.array([r, r, shape.length() / 2 + r])
    if isinstance(shape, Sphere):
        return np.full(3, shape.radius())
    if isinstance(shape, Ellipsoid):
        return np.array([shape.a(), shape.b(), shape.c()])
    return np.zeros(3)


def LowestToolPoint(
    centerline_W: np.ndarray, tool_points_T: np.ndarray, roll: float
) -> tuple[int, float]:
    """(row, z): the hose point (N, 3; m, W) where the tool, centred on the hose with x_T
    along its tangent and rolled by `roll` (rad) about it, reaches lowest, and that
    lowest world z (m) of its points (ToolPoints)."""
    points = np.atleast_2d(centerline_W)
    tangents = np.gradient(points, axis=0) if len(points) > 1 else np.array([[1.0, 0.0, 0.0]])
    lowest = [
        float(p[2] + np.min(OrientationFromVector(t, roll).matrix()[2] @ tool_points_T.T))
        for p, t in zip(points, tangents, strict=True)
    ]
    row = int(np.argmin(lowest))
    return row, lowest[row]


def CheckHoseReachable(
    centerline_B: np.ndarray,
    X_WB: RigidTransform,
    workspace: WorkspaceConfig,
    reach: ArmReach,
    clearance: float,
    arm: str,
    tool_points_T: np.ndarray,
    roll: float = 0.0,
) -> None:
    """Refuses (ConfigurationError, one line naming the point) a hose centerline (N, 3; m,
    the arm's base frame B at X_WB) with a point beyond the arm's reach, nearer a side
    wall or the ceiling than the tool's clearance, or where the tool held along it with
    `roll` (rad; ToolPoints in T) would reach below the floor (module docstring)."""
    points = np.atleast_2d(centerline_B)
    distances = np.linalg.norm(X_WB.multiply(points.T).T - reach.p_WS, axis=1)
    far = int(np.argmax(distances))
    if distances[far] > reach.reach:
        raise ConfigurationError(
            f"hose point {far} {np.round(points[far], 3).tolist()} (m, base frame) is "
            f"{distances[far]:.3f} m from {arm}'s shoulder, beyond its reach of "
            f"{reach.reach:.3f} m to the tool centre: move the hose nearer the arm"
        )
    CheckToolAboveFloor(points, X_WB, workspace, tool_points_T, roll)
    walls = [
        (points[:, axis] - workspace.Lower()[axis], axis, "lower", workspace.Lower()[axis])
        for axis in range(2)
    ] + [
        (workspace.Upper()[axis] - points[:, axis], axis, "upper", workspace.Upper()[axis])
        for axis in range(3)
    ]
    for gaps, axis, side, wall in walls:
        row = int(np.argmin(gaps))
        if gaps[row] < clearance:
            raise ConfigurationError(
                f"hose point {row} {np.round(points[row], 3).tolist()} (m, base frame) is "
                f"{1000 * gaps[row]:.0f} mm from the workspace's {'xyz'[axis]} {side} wall "
                f"({wall:g} m); the ToF tool needs {1000 * clearance:.0f} mm of clearance "
                "(its farthest body from its centre): move the hose or widen `workspace`"
            )


def CheckToolAboveFloor(
    centerline_B: np.ndarray,
    X_WB: RigidTransform,
    workspace: WorkspaceConfig,
    tool_points_T: np.ndarray,
    roll: float,
) -> None:
    """Refuses (ConfigurationError, one line) a hose (N, 3; m, frame B at X_WB) along which
    the tool, held as the followers hold it with `roll` (rad), would reach below the
    workspace's z lower wall (the floor over the table; a B level with the world)."""
    floor = workspace.Lower()[2]
    centerline_W = X_WB.multiply(np.atleast_2d(centerline_B).T).T
    row, lowest_W = LowestToolPoint(centerline_W, tool_points_T, roll)
    lowest = lowest_W - X_WB.translation()[2]
    if lowest < floor:
        point = np.round(np.atleast_2d(centerline_B)[row], 4).tolist()
        raise ConfigurationError(
            f"hose point {row} {point} (m, base frame): the ToF tool held along it with "
            f"tool_roll_deg {np.degrees(roll):g} reaches {1000 * (floor - lowest):.0f} mm "
            f"below the workspace's z lower wall ({floor:g} m): roll the tool about the hose "
            "(tool_roll_deg, e.g. -45 for a hose on the table) or raise the hose"
        )
