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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex

from guidedarm.systems.errors import ConfigurationError
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


def CheckHoseReachable(
    centerline_B: np.ndarray,
    X_WB: RigidTransform,
    workspace: WorkspaceConfig,
    reach: ArmReach,
    clearance: float,
    arm: str,
) -> None:
    """Refuses (ConfigurationError, one line naming the point) a hose centerline (N, 3; m,
    the arm's base frame B at X_WB) with a point beyond the arm's reach, or nearer a
    workspace wall than the tool's clearance."""
    points = np.atleast_2d(centerline_B)
    distances = np.linalg.norm(X_WB.multiply(points.T).T - reach.p_WS, axis=1)
    far = int(np.argmax(distances))
    if distances[far] > reach.reach:
        raise ConfigurationError(
            f"hose point {far} {np.round(points[far], 3).tolist()} (m, base frame) is "
            f"{distances[far]:.3f} m from {arm}'s shoulder, beyond its reach of "
            f"{reach.reach:.3f} m to the tool centre: move the hose nearer the arm"
        )
    walls = [
        (points[:, axis] - workspace.Lower()[axis], axis, "lower", workspace.Lower()[axis])
        for axis in range(3)
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
