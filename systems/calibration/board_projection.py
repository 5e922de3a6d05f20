"""Images of a flat printed board seen by a camera with lens distortion, by projection.

The image is what a camera with `intrinsics` (OpenCV's pinhole model and k1 k2 p1 p2 k3
distortion) at pose X_CB sees of a planar texture lying in the plane z = 0 of the board
frame B: every pixel's ray is undistorted, intersected with that plane and the texture is
sampled there. Pixels are integrated over `supersampling` x `supersampling` sub-pixels.
Used to make calibration photos of known optics (tests, the documentation's pictures).
"""

from __future__ import annotations

import cv2
import numpy as np
from pydrake.math import RigidTransform

from guidedarm.systems.calibration.charuco_board import BoardImage, BoardSpec
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

BACKGROUND_GREY = 110
# Texture pixels per board square: finer than the image's sub-pixels at working distances.
BOARD_TEXTURE_PX_PER_SQUARE = 200
# The ray field is smooth: it is undistorted on a grid of this step (sub-pixels) and
# interpolated (bicubic) in between; the interpolation error is below 1e-3 px.
_GRID_STEP = 8


def UndistortedRays(intrinsics: CameraIntrinsics, supersampling: int) -> np.ndarray:
    """Normalised image coordinates (x/z, y/z) of the ray through the centre of every
    sub-pixel (height*k x width*k x 2), k = supersampling."""
    k = supersampling
    width, height = intrinsics.width * k, intrinsics.height * k
    u = np.arange(0, width + _GRID_STEP, _GRID_STEP, dtype=float)
    v = np.arange(0, height + _GRID_STEP, _GRID_STEP, dtype=float)
    grid = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 1, 2)
    pixels = (grid + 0.5) / k - 0.5  # sub-pixel centres in the camera's pixel coordinates
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    rays = cv2.undistortPointsIter(
        pixels, intrinsics.camera_matrix(), intrinsics.distortion_vector(), None, None, criteria
    ).reshape(len(v), len(u), 2)
    # Grid node (i, j) holds sub-pixel (i, j) * step: sample it at sub-pixel / step.
    map_x = np.tile(np.arange(width, dtype=np.float32) / _GRID_STEP, (height, 1))
    map_y = np.tile(np.arange(height, dtype=np.float32)[:, None] / _GRID_STEP, (1, width))
    return cv2.remap(rays.astype(np.float32), map_x, map_y, cv2.INTER_CUBIC)


def ProjectPlanarTexture(
    texture: np.ndarray,
    pixels_per_m: float,
    X_CB: RigidTransform,
    intrinsics: CameraIntrinsics,
    supersampling: int = 2,
    rays: np.ndarray | None = None,
    origin_px: float = 0.0,
) -> np.ndarray:
    """The greyscale uint8 image (height x width) of `texture` (greyscale, columns along
    x_B, rows along y_B, pixels_per_m; B's origin at texture coordinate origin_px along both,
    0: the top-left pixel's outer corner) seen from a camera at X_CB; the rest of the view
    is a grey background. `rays` may pass UndistortedRays(intrinsics, supersampling)
    computed once for many views."""
    if rays is None:
        rays = UndistortedRays(intrinsics, supersampling)
    R = X_CB.rotation().matrix()
    M = np.column_stack([R[:, 0], R[:, 1], X_CB.translation()])
    if abs(np.linalg.det(M)) < 1e-12:
        raise ConfigurationError("the camera lies in the board's plane")
    A = np.linalg.inv(M).astype(np.float32)
    x, y = rays[..., 0], rays[..., 1]
    h = [A[i, 0] * x + A[i, 1] * y + A[i, 2] for i in range(3)]
    # Rays that meet the plane behind the camera (h[2] <= 0) sample the background.
    depth = np.where(h[2] > 0, h[2], np.float32(1e-12))
    scale = np.float32(pixels_per_m)
    offset = np.float32(origin_px - 0.5)
    map_x = np.where(h[2] > 0, h[0] / depth * scale + offset, np.float32(-1e6))
    map_y = np.where(h[2] > 0, h[1] / depth * scale + offset, np.float32(-1e6))
    fine = cv2.remap(
        texture,
        map_x,
        map_y,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=BACKGROUND_GREY,
    )
    return cv2.resize(fine, (intrinsics.width, intrinsics.height), interpolation=cv2.INTER_AREA)


def BoardPhotos(
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
    views_X_BC: list[RigidTransform],
    supersampling: int = 2,
) -> list[np.ndarray]:
    """Greyscale photos of the printed board (a white margin of one square around it) from
    camera poses X_BC, through the lens of `intrinsics`."""
    pixels_per_m = BOARD_TEXTURE_PX_PER_SQUARE / spec.square_m
    margin = BOARD_TEXTURE_PX_PER_SQUARE
    texture = BoardImage(spec, pixels_per_m, margin_px=margin)
    rays = UndistortedRays(intrinsics, supersampling)
    return [
        ProjectPlanarTexture(
            texture, pixels_per_m, X_BC.inverse(), intrinsics, supersampling, rays, margin
        )
        for X_BC in views_X_BC
    ]
