"""AddPathFollowingOverlays: the ToF tool's view, the detected path and the tool-centre path."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Role
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder, System
from pydrake.systems.primitives import MatrixGain

from guidedarm.diagrams.builder_checks import CheckStationWiring
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.scene.hose_geometry import ReadCenterline
from guidedarm.systems.tof.tof_tool_sensor import MakeDetectionGrid
from guidedarm.systems.tof.tof_tool_sensor_math import ConeRays
from guidedarm.systems.visualization.detected_path_overlay import DetectedPathOverlay
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD, FrameTrailOverlay
from guidedarm.systems.visualization.overlay_geometry import (
    OVERLAYS,
    TOOL_RGBA,
    AimCamera,
    ArmFramePoses,
    ViewFromBeyond,
)
from guidedarm.systems.visualization.see_through_geometry import SeeThroughGeometry
from guidedarm.systems.visualization.tof_tool_overlay import ToFToolOverlay

TOF_PATH = f"{OVERLAYS}/tof"
DETECTED_PATH = f"{OVERLAYS}/detected_path"
TOOL_CENTRE_PATH = f"{OVERLAYS}/tool_centre"


def AddPathFollowingOverlays(
    builder: DiagramBuilder,
    meshcat: Meshcat | None,
    station: Diagram,
    follower: System,
    plant: MultibodyPlant,
    scenario: StationScenario,
    arm: str,
    tof_name: str,
) -> None:
    """Wires a ToFToolOverlay (/overlays/tof), a DetectedPathOverlay
    (/overlays/detected_path) and the trail of the tool centre O (/overlays/tool_centre)
    from the station's `<arm>.position_measured` and the follower's outputs: the ToF
    overlay draws the reading of the follower's latest step (`step_record`'s ranges and
    validity, `detections`, `detection_errors`), i.e. what the algorithm used, at no cost;
    wiring the station's `<tof_name>.*` ports instead would show every reading, each
    costing a ray cast. `plant` holds the arm and the ToF tool (e.g. the IK's plant). The
    camera looks at the scenario's hose, seen from beyond it. Nothing without a Meshcat."""
    if meshcat is None:
        return
    CheckStationWiring(
        builder,
        station,
        outputs=[f"{arm}.position_measured"],
        new_systems=["tof_overlay", "detected_path_overlay", "tool_centre_overlay"],
    )
    tof = scenario.ToFTool(tof_name)
    poses = ArmFramePoses(plant, plant.GetModelInstanceByName(arm))
    tool = GetScopedFrame(plant, tof.tool_frame, f"tof_tools.{tof_name}.tool_frame")
    q_measured = station.GetOutputPort(f"{arm}.position_measured")
    rays = ConeRays(np.radians(tof.cone_angle_deg), tof.rings)
    grid = MakeDetectionGrid(plant, tof)
    view = builder.AddNamedSystem(
        "tof_overlay",
        ToFToolOverlay(
            meshcat, TOF_PATH, poses, tool, grid, rays, tof.max_range, sensor_period=OVERLAY_PERIOD
        ),
    )
    builder.Connect(q_measured, view.GetInputPort("position"))
    record = follower.GetOutputPort("step_record")
    for port in ("ranges", "valid"):
        fields = [RECORD_FIELDS.index(f"{port.rstrip('s')}_{k}") for k in range(1, 7)]
        pick = builder.AddNamedSystem(
            f"tof_overlay_{port}", MatrixGain(np.eye(len(RECORD_FIELDS))[fields])
        )
        builder.Connect(record, pick.get_input_port())
        builder.Connect(pick.get_output_port(), view.GetInputPort(port))
    for port in ("detections", "detection_errors"):
        builder.Connect(follower.GetOutputPort(port), view.GetInputPort(port))
    detected = builder.AddNamedSystem(
        "detected_path_overlay", DetectedPathOverlay(meshcat, DETECTED_PATH)
    )
    builder.Connect(follower.GetOutputPort("step_record"), detected.get_input_port())
    centre = builder.AddNamedSystem(
        "tool_centre_overlay", FrameTrailOverlay(meshcat, TOOL_CENTRE_PATH, poses, tool, TOOL_RGBA)
    )
    builder.Connect(q_measured, centre.get_input_port())
    hose = HoseIllustrationPaths(station)
    if hose:
        builder.AddNamedSystem("see_through_hose", SeeThroughGeometry(meshcat, hose))
    if scenario.hose is not None:
        centerline = ReadCenterline(scenario.hose.centerline)
        AimCamera(meshcat, centerline, ViewFromBeyond(centerline, np.zeros(3)), margin=0.95)


def HoseIllustrationPaths(station: Diagram) -> list[str]:
    """Meshcat paths of the hose illustration geometry of a station with a SceneGraph named
    `scene_graph` (world-frame geometries named `hose_<i>`, drawn by the MeshcatVisualizer
    under /drake/illustration); none without."""
    if not station.HasSubsystemNamed("scene_graph"):
        return []
    inspector = station.GetSubsystemByName("scene_graph").model_inspector()
    world = inspector.world_frame_id()
    names = [
        inspector.GetName(g)
        for g in inspector.GetAllGeometryIds(Role.kIllustration)
        if inspector.GetFrameId(g) == world
    ]
    return [f"/drake/illustration/{name}" for name in names if name.startswith("hose_")]
