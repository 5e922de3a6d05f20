"""AddPanelOverlays: the camera's view, the estimated and the true panel frame, the target."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Cylinder, Meshcat, Rgba
from pydrake.math import RigidTransform
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem

from guidedarm.diagrams.builder_checks import CheckStationWiring
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics, SwitchSpec
from guidedarm.systems.panel.panel_operation import CameraArmKinematics
from guidedarm.systems.visualization.overlay_geometry import (
    OVERLAYS,
    TRUTH_RGBA,
    AimCamera,
    ArmFramePoses,
    DrawTriad,
)
from guidedarm.systems.visualization.panel_estimate_overlay import PanelEstimateOverlay

PANEL_PATH = f"{OVERLAYS}/panel"


def AddPanelOverlays(
    builder: DiagramBuilder,
    meshcat: Meshcat | None,
    station: Diagram,
    sequencer: LeafSystem,
    kinematics: CameraArmKinematics,
    arm: str,
    intrinsics: CameraIntrinsics,
    switch: SwitchSpec,
    panel_model: str,
    panel_frame: str = "plate",
) -> None:
    """Adds a PanelEstimateOverlay (camera pyramid from `kinematics` at the station's
    `<arm>.position_measured`, the sequencer's `X_WP_estimated`) under /overlays/panel and,
    from the simulated station's plant (ground truth), the true panel frame P
    (`panel_frame` of `panel_model`, /overlays/panel/true_panel) and the target `switch`
    (a yellow ring on its cap, /overlays/panel/target_switch); aims the camera at the
    panel. Nothing without a Meshcat."""
    if meshcat is None:
        return
    CheckStationWiring(
        builder, station, outputs=[f"{arm}.position_measured"], new_systems=["panel_overlay"]
    )
    poses = ArmFramePoses(kinematics.plant, kinematics.plant.GetModelInstanceByName(arm))
    view = builder.AddNamedSystem(
        "panel_overlay",
        PanelEstimateOverlay(meshcat, PANEL_PATH, poses, kinematics.camera_frame, intrinsics),
    )
    builder.Connect(
        station.GetOutputPort(f"{arm}.position_measured"), view.GetInputPort("position")
    )
    builder.Connect(sequencer.GetOutputPort("X_WP_estimated"), view.GetInputPort("X_WP_estimated"))
    if not station.HasSubsystemNamed("plant"):
        return
    plant = station.GetSubsystemByName("plant")
    frame = plant.GetFrameByName(panel_frame, plant.GetModelInstanceByName(panel_model))
    X_WP = frame.CalcPoseInWorld(plant.CreateDefaultContext())
    meshcat.SetTransform(f"{PANEL_PATH}/true_panel", X_WP)
    DrawTriad(meshcat, f"{PANEL_PATH}/true_panel", length=0.06, radius=0.0012)
    target = f"{PANEL_PATH}/target_switch"
    # A flat ring (a short cylinder) just in front of the cap, its axis the panel normal.
    p_PS = np.asarray(switch.position, float) + [0.0, 0.0, 0.002]
    meshcat.SetObject(
        target, Cylinder(1.6 * switch.radius_m, 0.002), Rgba(*TRUTH_RGBA.rgba[:3], 0.8)
    )
    meshcat.SetTransform(target, X_WP @ RigidTransform(p_PS))
    # The panel and the space in front of it where the camera measures and the tip presses,
    # seen from the side, above: the arm reaches in from the front without hiding it.
    region_P = ([-0.08, -0.08, 0.0], [0.2, 0.08, 0.0], [0.06, 0.0, 0.3], p_PS)
    R_WP = X_WP.rotation().matrix()
    AimCamera(
        meshcat,
        np.array([X_WP @ np.asarray(p) for p in region_P]),
        0.6 * R_WP[:, 2] + R_WP[:, 0] + [0.0, 0.0, 0.5],
        margin=1.5,
    )
