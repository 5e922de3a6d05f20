"""AddWaypointOverlays: the planner's waypoints, neighbourhoods and commanded TCP trail."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, OutputPort

from guidedarm.systems.planning.acceleration_planner_math import AccelerationPlanning
from guidedarm.systems.visualization.frame_trail_overlay import FrameTrailOverlay
from guidedarm.systems.visualization.overlay_geometry import (
    OVERLAYS,
    PLAN_RGBA,
    TRUTH_RGBA,
    AimCamera,
    ArmFramePoses,
    DrawPoint,
    ViewFromBeyond,
)

WAYPOINTS_PATH = f"{OVERLAYS}/waypoints"
TCP_TRAIL_PATH = f"{OVERLAYS}/tcp_commanded"


def AddWaypointOverlays(
    builder: DiagramBuilder,
    meshcat: Meshcat | None,
    planning: AccelerationPlanning,
    position_commanded: OutputPort,
    q_start: np.ndarray,
) -> FrameTrailOverlay | None:
    """Draws the waypoints of `planning` (its base frame placed in the world by its plant)
    under /overlays/waypoints: each intermediate one inside its translucent neighbourhood
    sphere (radius epsilon, the planner's neighbourhood_radius), the final one inside its
    position tolerance, the start TCP, and the straight legs between them; adds a
    FrameTrailOverlay of the TCP under the commanded joints (`position_commanded`) and aims
    the camera at the task. Nothing without a Meshcat; returns the trail system."""
    if meshcat is None:
        return None
    kinematics = planning.kinematics
    poses = ArmFramePoses(kinematics.plant, kinematics.instance)
    X_WB, X_WT0 = poses.Poses(q_start, [kinematics.base_frame, kinematics.tool_frame])
    points = np.array([X_WB @ w[:3] for w in np.atleast_2d(planning.waypoints)])
    radius = planning.parameters.neighbourhood_radius
    meshcat.Delete(WAYPOINTS_PATH)
    for k, p in enumerate(points):
        path = f"{WAYPOINTS_PATH}/{k + 1}"
        last = k == len(points) - 1
        DrawPoint(meshcat, f"{path}/point", p, 0.008, PLAN_RGBA)
        around = planning.parameters.position_tolerance if last else radius
        meshcat.SetObject(f"{path}/neighbourhood", Sphere(max(around, 0.004)), Rgba(1, 0, 1, 0.25))
        meshcat.SetTransform(f"{path}/neighbourhood", RigidTransform(p))
    DrawPoint(meshcat, f"{WAYPOINTS_PATH}/start", X_WT0.translation(), 0.008, TRUTH_RGBA)
    legs = np.vstack([X_WT0.translation(), points]).T
    meshcat.SetLine(f"{WAYPOINTS_PATH}/legs", legs, 1.0, Rgba(1, 0, 1, 0.5))
    trail = builder.AddNamedSystem(
        "tcp_commanded_overlay",
        FrameTrailOverlay(meshcat, TCP_TRAIL_PATH, poses, kinematics.tool_frame, PLAN_RGBA),
    )
    builder.Connect(position_commanded, trail.get_input_port())
    task = np.vstack([legs.T, points - radius, points + radius])
    AimCamera(meshcat, task, ViewFromBeyond(task, X_WB.translation(), 0.6), margin=1.3)
    return trail
