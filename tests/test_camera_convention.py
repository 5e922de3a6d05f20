"""One principal-point convention: the camera file's intrinsics are those of the images the
panel task renders (OpenCV pixel coordinates, Drake's CameraInfo centre)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.geometry import (
    Box,
    FramePoseVector,
    GeometryFrame,
    GeometryInstance,
    MakeRenderEngineVtk,
    PerceptionProperties,
    RenderEngineVtkParams,
    RenderLabel,
    Rgba,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.panel.panel_files import (
    DEFAULT_CAMERA_FILE,
    IntrinsicsFromCameraConfig,
    LoadCameraIntrinsics,
    SupersampledCameraConfig,
)
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.markers.image_degradation import DegradationConfig, DegradeImage


def PanelCamera():
    _, scenario, _ = LoadScenario("panel_operation", [])
    return scenario.station.cameras[scenario.camera]


@pytest.mark.parametrize("k", [1, 3])
def test_camera_file_states_the_rendered_intrinsics(k):
    file = LoadCameraIntrinsics(DEFAULT_CAMERA_FILE)
    rendered = IntrinsicsFromCameraConfig(SupersampledCameraConfig(PanelCamera(), k), k)
    assert (rendered.width, rendered.height) == (file.width, file.height)
    for key in ("fx", "fy", "cx", "cy"):
        assert getattr(rendered, key) == pytest.approx(getattr(file, key), abs=1e-9), key
    assert (file.cx, file.cy) == (959.5, 539.5)


class SquareScene:
    """A white 8 mm square facing the camera (its image centroid is the projection of its
    centre), rendered through the panel task's camera pipeline with `k` x supersampling."""

    def __init__(self, k: int) -> None:
        builder = DiagramBuilder()
        self.scene_graph = builder.AddSystem(SceneGraph())
        self.scene_graph.AddRenderer(
            "vtk", MakeRenderEngineVtk(RenderEngineVtkParams(default_clear_color=[0.0] * 3))
        )
        self.source = self.scene_graph.RegisterSource("square")
        self.frame = self.scene_graph.RegisterFrame(self.source, GeometryFrame("square"))
        square = GeometryInstance(RigidTransform(), Box(0.008, 0.008, 1e-4), "square")
        properties = PerceptionProperties()
        properties.AddProperty("phong", "diffuse", Rgba(1, 1, 1, 1))
        properties.AddProperty("label", "id", RenderLabel(1))
        square.set_perception_properties(properties)
        self.scene_graph.RegisterGeometry(self.source, self.frame, square)
        self.context = self.scene_graph.CreateDefaultContext()
        config = SupersampledCameraConfig(PanelCamera(), k)
        config.renderer_name = "vtk"
        self.camera, _ = config.MakeCameras()
        self.k = k

    def Centroid(self, p_CQ: np.ndarray) -> np.ndarray:
        """Intensity-weighted centroid (u, v) of the square centred at p_CQ (camera C)."""
        poses = FramePoseVector()
        poses.set_value(self.frame, RigidTransform(p_CQ))
        self.scene_graph.get_source_pose_port(self.source).FixValue(self.context, poses)
        query = self.scene_graph.get_query_output_port().Eval(self.context)
        image = query.RenderColorImage(
            self.camera, self.scene_graph.world_frame_id(), RigidTransform()
        )
        reduced = DegradeImage(np.asarray(image.data), DegradationConfig(supersampling=self.k))
        weight = reduced[:, :, :3].astype(float).sum(axis=2)
        v, u = np.indices(weight.shape)
        return np.array([(u * weight).sum(), (v * weight).sum()]) / weight.sum()


def test_a_rendered_point_lands_on_the_camera_file_pixel():
    """Squares at 1/10 px steps: the mean offset of their image centroids from the camera
    file's projection is the principal-point error (the renderer's aliasing, whole pixels,
    averages out over a pixel of shifts; without the compensation it is -0.5 px)."""
    file = LoadCameraIntrinsics(DEFAULT_CAMERA_FILE)
    scene = SquareScene(1)
    z = 0.5
    errors = []
    for step in range(10):
        shift = step / 10 * z / file.fx
        p_CQ = np.array([0.06 + shift, -0.04 + shift, z])
        expected = np.array([file.cx + file.fx * p_CQ[0] / z, file.cy + file.fy * p_CQ[1] / z])
        errors.append(scene.Centroid(p_CQ) - expected)
    mean = np.mean(errors, axis=0)
    assert np.all(np.abs(mean) < 0.05), f"principal point off by {mean} px"
