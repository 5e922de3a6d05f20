"""CameraErrors: how a real camera differs from its camera file, and the true camera it makes.

Drake renders pinhole images. A camera with lens distortion is rendered as a pinhole
camera of the true focal length and principal point on a canvas wide enough to hold the
distorted field of view (TrueCamera), and the render is remapped to the distorted image
(lens_distortion_math.LensRemap, applied by the LensDistortion system).
"""

import copy
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraConfig

from guidedarm.systems.cell_errors.distributions import DrawErrors, VectorError
from guidedarm.systems.cell_errors.lens_distortion_math import LensRemap, MakeLensRemap
from guidedarm.systems.config_checks import CheckFields
from guidedarm.systems.errors import ConfigurationError


@dataclass
class CameraErrors:
    """The errors of one camera (station.errors.cameras.<camera>, marker_view's
    camera_errors); numbers or Drake distributions, drawn once per run.

    focal_error_px: [dfx, dfy], the true focal lengths minus the camera file's (px).
    principal_point_error_px: [dcx, dcy], the true principal point minus the file's (px).
    distortion: the true lens, OpenCV's [k1, k2, p1, p2, k3]; empty: none.
    X_mount_error: the camera's true pose in its nominal frame (the hand-eye error).
    """

    focal_error_px: VectorError = field(default_factory=list)
    principal_point_error_px: VectorError = field(default_factory=list)
    distortion: VectorError = field(default_factory=list)
    X_mount_error: Transform = field(default_factory=Transform)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field (lengths of drawn lists)."""
        CheckFields(self)
        for name, size in (("focal_error_px", 2), ("principal_point_error_px", 2)):
            _CheckLength(getattr(self, name), name, (0, size))
        _CheckLength(self.distortion, "distortion", (0, 5))
        if self.X_mount_error.base_frame:
            raise ConfigurationError(
                "X_mount_error.base_frame cannot be set (the error is in the camera's frame)"
            )


@dataclass
class TrueCamera:
    """The camera to render (CameraConfig: true intrinsics, on a canvas that holds the
    distorted view), the lens remap to the camera's own image size (None: no distortion)
    and the camera's true pose in its nominal frame X_CnC."""

    config: CameraConfig
    remap: LensRemap | None
    X_mount_error: RigidTransform


def MakeTrueCamera(config: CameraConfig, errors: CameraErrors) -> TrueCamera:
    """The true camera of `config` with drawn `errors` (see TrueCamera)."""
    errors = DrawErrors(errors, None, "camera_errors")
    errors.Validate()
    intrinsics = config.MakeCameras()[0].core().intrinsics()
    fx, fy = intrinsics.focal_x(), intrinsics.focal_y()
    cx, cy = intrinsics.center_x(), intrinsics.center_y()
    dfx, dfy = errors.focal_error_px or (0.0, 0.0)
    dcx, dcy = errors.principal_point_error_px or (0.0, 0.0)
    K = np.array([[fx + dfx, 0.0, cx + dcx], [0.0, fy + dfy, cy + dcy], [0.0, 0.0, 1.0]])
    true = copy.deepcopy(config)
    remap = None
    if errors.distortion and any(errors.distortion):
        remap = MakeLensRemap(K, np.asarray(errors.distortion, float), config.width, config.height)
        true.width, true.height = remap.render_width, remap.render_height
        K = remap.K_render
    if (true.width, true.height) != (config.width, config.height) or dfx or dfy or dcx or dcy:
        true.focal = CameraConfig.FocalLength(x=K[0, 0], y=K[1, 1])
        true.center_x, true.center_y = K[0, 2], K[1, 2]
    return TrueCamera(true, remap, errors.X_mount_error.GetDeterministicValue())


def ScaledCameraErrors(errors: CameraErrors, k: int) -> CameraErrors:
    """The errors of a camera rendered at k times its resolution (pixel errors times k)."""
    errors = DrawErrors(errors, None, "camera_errors")
    return CameraErrors(
        focal_error_px=[k * x for x in errors.focal_error_px],
        principal_point_error_px=[k * x for x in errors.principal_point_error_px],
        distortion=list(errors.distortion),
        X_mount_error=errors.X_mount_error,
    )


def _CheckLength(values, name: str, sizes: tuple[int, ...]) -> None:
    if isinstance(values, list) and len(values) not in sizes:
        raise ConfigurationError(f"{name} must hold {sizes[-1]} values, got {len(values)}")
