"""Unit-testing a LeafSystem the Drake way, as a pytest file.

A LeafSystem is tested on its own, without a Diagram or a Simulator: make its context
(CreateDefaultContext), fix each input port to a value (FixValue; a numpy vector for a
vector port, the port's value type, e.g. an ImageRgba8U, for an abstract one), evaluate
the output ports (Eval) and assert numbers. Copy a test and put your own system in it.

Run:  .venv/bin/pytest examples/test_my_leaf_system.py
"""

import numpy as np
from pydrake.systems.sensors import CameraConfig, ImageRgba8U

from guidedarm.diagrams.panel.panel_camera_rig import LookAt, PanelCameraRig
from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.systems.markers.image_degradation import DegradationConfig, ImageDegradation
from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver


def test_image_degradation_averages_pixel_blocks_and_dims_the_light():
    system = ImageDegradation(DegradationConfig(supersampling=2, lighting=0.5))
    context = system.CreateDefaultContext()
    image = ImageRgba8U(4, 2)  # width 4, height 2: two 2 x 2 blocks
    image.mutable_data[:, :, :3] = [[[100] * 3, [200] * 3, [10] * 3, [30] * 3]] * 2
    image.mutable_data[:, :, 3] = 255
    system.GetInputPort("color_image").FixValue(context, image)
    out = np.asarray(system.GetOutputPort("color_image").Eval(context).data)
    assert out.shape == (1, 2, 4)
    np.testing.assert_array_equal(out[0, :, 0], [75, 10])  # 0.5 x mean(100, 200), 0.5 x 20
    np.testing.assert_array_equal(out[0, :, 3], [255, 255])  # alpha untouched


def test_marker_pose_estimator_finds_the_panel_in_a_rendered_image():
    camera = CameraConfig(width=1280, height=720, focal=CameraConfig.FocalLength(x=910, y=910))
    rig = PanelCameraRig(camera, supersampling=2)  # the panel rendered by VTK, P = world
    X_PC = LookAt(np.array([0.02, 0.05, 0.30]), np.array([0.06, 0.0, 0.0]))
    rendered = rig.Render(X_PC)
    solver = MarkerPoseSolver(rig.intrinsics, LoadPanelSpec(DEFAULT_PANEL_FILE))
    system = MarkerPoseEstimator(solver)
    context = system.CreateDefaultContext()
    image = ImageRgba8U(rendered.shape[1], rendered.shape[0])
    image.mutable_data[:] = rendered
    system.GetInputPort("color_image").FixValue(context, image)
    assert system.GetOutputPort("valid").Eval(context)[0] == 1.0
    assert sorted(system.GetOutputPort("ids").Eval(context)) == [7, 42]
    X_CP = system.GetOutputPort("X_CP").Eval(context)
    X_CP_true = X_PC.inverse()
    assert np.linalg.norm(X_CP.translation() - X_CP_true.translation()) < 0.001  # m
    angle = (X_CP.rotation().inverse() @ X_CP_true.rotation()).ToAngleAxis().angle()
    assert np.degrees(angle) < 0.3
