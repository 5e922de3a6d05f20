"""The marker estimator with your own camera, in a Drake diagram.

Your camera, a Drake CameraConfig (its size and calibration: focal lengths and principal
point in pixels), looks at the switch panel of Annusewicz-Mistal et al. (two 50 mm ArUco
markers, models/panel/panel.yaml) in a station scene. The station renders the camera's
image with VTK; MarkerPoseEstimator turns it into X_CP, the pose of the panel frame P
(the left marker's frame) in the camera frame C (x right, y down, z forward). The script
prints the estimate against the simulation's truth X_CP = X_WC^-1 X_WP.

Run:  .venv/bin/python examples/marker_estimator_with_your_camera.py
Put your own camera's numbers in STATION (and where it looks from in X_PB, here relative
to the panel). On hardware, MakeStation(scenario, kind="hardware") gives the same
`my_camera.rgb_image` port from OpenCV's VideoCapture (station.hardware.cameras).
"""

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.math import RollPitchYaw
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.panel.panel_files import (
    DEFAULT_PANEL_FILE,
    IntrinsicsFromCameraConfig,
    LoadPanelSpec,
)
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver

# The panel welded to the world, and your camera 30 cm in front of it, tilted.
STATION = """
directives:
- add_model: {name: panel, file: package://guidedarm/panel/panel.sdf}
- add_weld: {parent: world, child: panel::plate}
cameras:
  my_camera:
    name: my_camera
    width: 1280
    height: 720
    focal: !FocalLength {x: 910.0, y: 910.0}
    center_x: 639.5
    center_y: 359.5
    X_PB:
      base_frame: panel::plate
      translation: [0.09, 0.06, 0.30]
      rotation: !Rpy {deg: [168.0, 6.0, 4.0]}
"""

scenario = yaml_load_typed(schema=StationScenario, data=STATION)
camera = scenario.cameras["my_camera"]
builder = DiagramBuilder()
station = builder.AddNamedSystem("station", MakeStation(scenario))
solver = MarkerPoseSolver(IntrinsicsFromCameraConfig(camera), LoadPanelSpec(DEFAULT_PANEL_FILE))
estimator = builder.AddNamedSystem("marker_pose_estimator", MarkerPoseEstimator(solver))
builder.Connect(station.GetOutputPort("my_camera.rgb_image"), estimator.GetInputPort("color_image"))
diagram = builder.Build()

context = diagram.CreateDefaultContext()
estimator_context = estimator.GetMyContextFromRoot(context)
estimate = estimator.GetOutputPort("estimate").Eval(estimator_context)
if not estimate.valid:
    raise SystemExit("no marker of the panel in view: move the camera (X_PB)")

# The truth from the simulation: the camera's pose (its sensor body S, then X_BC) and the
# panel's.
station_context = station.GetMyContextFromRoot(context)
X_WC = station.GetOutputPort("sim.my_camera.X_WS").Eval(station_context)
X_WC = X_WC @ camera.X_BC.GetDeterministicValue()
plant = station.GetSubsystemByName("plant")
plate = plant.GetFrameByName("plate", plant.GetModelInstanceByName("panel"))
X_WP = plate.CalcPoseInWorld(plant.GetMyContextFromRoot(context))
X_CP_true = X_WC.inverse() @ X_WP


def Show(name, X):
    p_mm = np.round(1000 * X.translation(), 2)
    rpy_deg = np.round(np.degrees(RollPitchYaw(X.rotation()).vector()), 3)
    print(f"X_CP {name}: p = {p_mm} mm, rpy = {rpy_deg} deg")


print(
    f"my_camera {camera.width} x {camera.height} px: markers {estimate.ids}, "
    f"reprojection error {estimate.reprojection_error_px:.3f} px"
)
Show("estimated", estimate.X_CP)
Show("truth    ", X_CP_true)
position_error = np.linalg.norm(estimate.X_CP.translation() - X_CP_true.translation())
rotation_error = (estimate.X_CP.rotation().inverse() @ X_CP_true.rotation()).ToAngleAxis().angle()
print(
    f"position error {1000 * position_error:.3f} mm, "
    f"rotation error {np.degrees(rotation_error):.3f} deg"
)
