"""AddJointTourOverlays: the commanded path of an arm's last link through a joint tour."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder, OutputPort

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.systems.visualization.frame_trail_overlay import FrameTrailOverlay
from guidedarm.systems.visualization.overlay_geometry import (
    OVERLAYS,
    PLAN_RGBA,
    AimCamera,
    ArmFramePoses,
    ViewFromBeyond,
)

FLANGE_TRAIL_PATH = f"{OVERLAYS}/flange_commanded"


def AddJointTourOverlays(
    builder: DiagramBuilder,
    meshcat: Meshcat | None,
    scenario: StationScenario,
    arm: str,
    position_commanded: OutputPort,
    joint_waypoints: list[np.ndarray],
) -> None:
    """Adds the trail of the arm's last link under the commanded joints (/overlays/
    flange_commanded) and aims the camera at the positions it takes at `joint_waypoints`.
    Nothing without a Meshcat."""
    if meshcat is None:
        return
    plant = MakeMultibodyPlant(scenario, [arm])
    instance = plant.GetModelInstanceByName(arm)
    flange = plant.get_body(plant.GetBodyIndices(instance)[-1]).body_frame()
    poses = ArmFramePoses(plant, instance)
    trail = builder.AddNamedSystem(
        "flange_commanded_overlay",
        FrameTrailOverlay(meshcat, FLANGE_TRAIL_PATH, poses, flange, PLAN_RGBA),
    )
    builder.Connect(position_commanded, trail.get_input_port())
    base = plant.get_body(plant.GetBodyIndices(instance)[0]).body_frame()
    points = [poses.Poses(np.asarray(q, float), [flange])[0].translation() for q in joint_waypoints]
    (X_WBase,) = poses.Poses(np.asarray(joint_waypoints[0], float), [base])
    points = np.array([*points, X_WBase.translation()])
    AimCamera(meshcat, points, ViewFromBeyond(points, X_WBase.translation(), 0.5), margin=1.3)
