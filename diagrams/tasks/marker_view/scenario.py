"""The `marker_view` task's scenario (MarkerViewScenario) and the camera keys it does not read."""

from dataclasses import dataclass, field

from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.panel.panel_files import (
    LoadEstimatorIntrinsics,
    LoadPanelSpec,
    ResolvePanelFile,
)
from guidedarm.diagrams.station.scenario import UNSUPPORTED_CAMERA_FIELDS, UnreadCameraKey
from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.config_checks import CheckFields, InRange
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import (
    CheckRenderedSupersampling,
    DegradationConfig,
)

# CameraConfig keys marker_view does not read: the station's, and the camera's pose and name
# (the view places the camera by distance_m and angle_deg and renders one colour image).
UNREAD_CAMERA_KEYS = (*UNSUPPORTED_CAMERA_FIELDS, "fps", "name", "X_PB", "X_BC")


@dataclass
class MarkerViewScenario:
    """One view of the marker panel from a free camera.

    distance_m: camera to the origin of P (the left marker, m, in (0, 5]).
    angle_deg: the view's turn about P's y axis (deg, in (-90, 90): P faces the camera).
    camera: its CameraConfig: its image size and optics; the keys of UNREAD_CAMERA_KEYS
        (pose, rate, depth, name, ...) are refused, the view places the camera.
    supersampling: the camera is rendered at this many times its resolution (1..8, and
        width x height x supersampling^2 <= MAX_RENDER_PIXELS).
    degradation: lighting, blur, noise (its supersampling must stay 1: the top-level key
        sets it; its noise seed is the scenario's random_seed).
    random_seed: the scenario's random seed (the image noise, the draw of camera_errors).
    camera_errors: how the real camera differs from `camera` (CameraErrors, the fields
        of station.errors.cameras.<camera>; numbers or distributions drawn from
        random_seed): it renders through them, the estimator uses `camera`.
    panel_file: the PANEL.yaml the view shows and the estimator reads: a path, absolute or
        relative to the working directory, or a name under models/ (its model is
        generated from it).
    estimator_camera_file: the estimator's camera model, a CAMERA.yaml (e.g. written by
        `guidedarm calibrate camera`; a path, absolute or relative to the working
        directory, or a name under models/) of the camera's width x height; empty: the
        intrinsics of `camera` (no distortion).
    """

    task: str = "marker_view"
    distance_m: float = InRange(0.0, 5.0, 0.3, low_open=True)
    angle_deg: float = InRange(-90.0, 90.0, 0.0, low_open=True, high_open=True)
    camera: CameraConfig = field(default_factory=CameraConfig)
    supersampling: int = InRange(1, 8, 3)
    degradation: DegradationConfig = field(default_factory=DegradationConfig)
    random_seed: int = 0
    camera_errors: CameraErrors = field(default_factory=CameraErrors)
    panel_file: str = "panel/panel.yaml"
    estimator_camera_file: str = ""

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, the rendered size, no key
        the view does not read (UNREAD_CAMERA_KEYS, degradation.supersampling) and the
        panel file."""
        CheckFields(self)
        LoadPanelSpec(ResolvePanelFile(self.panel_file))
        LoadEstimatorIntrinsics(self.estimator_camera_file, self.camera, "camera")
        changed = UnreadCameraKey(self.camera, UNREAD_CAMERA_KEYS)
        if changed:
            raise ConfigurationError(
                f"'camera.{changed}' has no effect on marker_view (the view places and "
                "renders one colour image): remove it"
            )
        CheckRenderedSupersampling(self.degradation, self.camera, self.supersampling)
