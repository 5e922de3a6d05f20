"""A free camera in front of the switch panel, for estimator accuracy studies and tests.

The panel model is welded with its frame P at the world origin; `Render(X_PC)` renders the
colour image that a camera at pose X_PC sees (VTK, the same renderer as the station), so
the ground truth of every image is exact. Images are rendered at `supersampling` times
the camera's resolution and reduced by DegradeImage (pixel-area integration, then the
optional lighting, blur and noise), as the simulated camera of the panel task does. The
arm plays no part here: this is the paper's IRB 1600 reference rig (section 3.2) in
simulation.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.geometry import MakeRenderEngineVtk, RenderEngineVtkParams
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.panel.panel_assets import COVER_CLOSED_M
from guidedarm.diagrams.panel.panel_files import (
    MODELS_PANEL_DIR,
    IntrinsicsFromCameraConfig,
    SupersampledCameraConfig,
)
from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.station.scenario import RENDERER_NAME
from guidedarm.systems.cell_errors.camera_errors import (
    CameraErrors,
    MakeTrueCamera,
    ScaledCameraErrors,
)
from guidedarm.systems.cell_errors.lens_distortion_math import Remap
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import DegradationConfig, DegradeImage


def LookAt(p_PC: np.ndarray, target_P: np.ndarray, up_P=(0.0, 1.0, 0.0)) -> RigidTransform:
    """Camera pose X_PC at p_PC whose optical axis (z) points at target_P, image up = up_P."""
    z = np.asarray(target_P, float) - np.asarray(p_PC, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up_P)
    if np.linalg.norm(x) < 1e-9:
        raise ConfigurationError("LookAt: the viewing direction is parallel to 'up'")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p_PC)


class PanelCameraRig:
    """The panel (models/panel/panel.sdf, P = world) and a camera configured by `camera`."""

    def __init__(
        self,
        camera: CameraConfig,
        supersampling: int = 3,
        panel_sdf: str | None = None,
        errors: CameraErrors | None = None,
    ) -> None:
        """camera: the nominal camera (its file), whose intrinsics `intrinsics` are; errors:
        how the real camera differs (drawn CameraErrors; None: it is exact): it renders
        through them."""
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
        scene_graph.AddRenderer(RENDERER_NAME, MakeRenderEngineVtk(RenderEngineVtkParams()))
        (self._panel,) = MakeParser(plant).AddModels(
            panel_sdf or str(MODELS_PANEL_DIR / "panel.sdf")
        )
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("plate", self._panel))
        plant.Finalize()
        self._plant = plant
        self._diagram = builder.Build()
        self._context = self._diagram.CreateDefaultContext()
        self._plant_context = plant.GetMyMutableContextFromRoot(self._context)
        self._scene_graph = scene_graph
        rendered = SupersampledCameraConfig(camera, supersampling)
        self._true = MakeTrueCamera(
            rendered, ScaledCameraErrors(errors or CameraErrors(), supersampling)
        )
        self._true.config.renderer_name = RENDERER_NAME
        self.color_camera, _ = self._true.config.MakeCameras()
        self.supersampling = supersampling
        self.intrinsics = IntrinsicsFromCameraConfig(rendered, supersampling)
        self._world = scene_graph.world_frame_id()

    def SetCover(self, closed: bool) -> None:
        """Slides the marker cover in front of the markers (closed) or behind the plate."""
        joint = self._plant.GetJointByName("cover_slide", self._panel)
        joint.set_translation(self._plant_context, COVER_CLOSED_M if closed else 0.0)

    def Render(
        self, X_PC: RigidTransform, degradation: DegradationConfig | None = None, stream: int = 0
    ) -> np.ndarray:
        """The RGBA uint8 image (height x width x 4) seen from camera pose X_PC; the
        degradation's own supersampling is replaced by the rig's."""
        query = self._scene_graph.get_query_output_port().Eval(
            self._scene_graph.GetMyContextFromRoot(self._context)
        )
        X_PC_true = X_PC @ self._true.X_mount_error
        image = np.asarray(query.RenderColorImage(self.color_camera, self._world, X_PC_true).data)
        if self._true.remap is not None:
            image = Remap(image, self._true.remap)
        params = dataclasses.replace(
            degradation or DegradationConfig(), supersampling=self.supersampling
        )
        return DegradeImage(image, params, stream)
