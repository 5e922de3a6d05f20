"""Camera poses for calibration photos of a board: varied distance, tilt and roll, with the
board placed across the whole image (its corners too, where distortion shows most).

Frames: B the board (charuco_board.py: z into the board), C the camera's optical frame.
"""

from __future__ import annotations

import cv2
import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from guidedarm.systems.calibration.charuco_board import BoardSpec
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

# Image margin (fraction of the side) the whole board must keep inside the image.
_MARGIN = 0.02


def _RotationTaking(a: np.ndarray, b: np.ndarray) -> RotationMatrix:
    """The smallest rotation R with R a = b (unit vectors, not opposite)."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        return RotationMatrix()
    rvec = axis / s * np.arctan2(s, c)
    return RotationMatrix(cv2.Rodrigues(rvec)[0])


def ProjectPoints(
    intrinsics: CameraIntrinsics, X_CB: RigidTransform, points_B: np.ndarray
) -> np.ndarray:
    """Where points_B (N x 3, m, in frame B) appear in the image (N x 2, px; the camera's
    distortion included) with B at X_CB in the camera's optical frame C."""
    rvec, _ = cv2.Rodrigues(X_CB.rotation().matrix())
    pixels, _ = cv2.projectPoints(
        points_B,
        rvec,
        X_CB.translation(),
        intrinsics.camera_matrix(),
        intrinsics.distortion_vector(),
    )
    return pixels.reshape(-1, 2)


def BoardCornersInView(
    spec: BoardSpec, intrinsics: CameraIntrinsics, X_CB: RigidTransform, margin: float = _MARGIN
) -> bool:
    """Whether the board's outline lies in the image (with `margin`) in front of the camera."""
    w, h = spec.size_m()
    edge = np.linspace(0, 1, 9)
    outline = np.vstack(
        [np.column_stack([edge * w, 0 * edge]), np.column_stack([edge * w, 0 * edge + h])]
        + [np.column_stack([0 * edge, edge * h]), np.column_stack([0 * edge + w, edge * h])]
    )
    points_B = np.column_stack([outline, np.zeros(len(outline))])
    points_C = (X_CB.rotation().matrix() @ points_B.T).T + X_CB.translation()
    if np.any(points_C[:, 2] <= 0.05):
        return False
    u, v = ProjectPoints(intrinsics, X_CB, points_B).T
    mu, mv = margin * intrinsics.width, margin * intrinsics.height
    return bool(
        np.all((u > mu) & (u < intrinsics.width - mu) & (v > mv) & (v < intrinsics.height - mv))
    )


def CalibrationViews(
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
    count: int,
    seed: int,
    distance_m: tuple[float, float] = (0.3, 0.5),
    max_tilt_deg: float = 35.0,
) -> list[RigidTransform]:
    """`count` camera poses X_BC from which the whole board is in view: distance from the
    board's centre in distance_m, the board tilted up to max_tilt_deg about x and y, rolled
    up to 30 deg, its centre placed on a grid of image points from the middle to the
    corners (seeded: the same arguments give the same views)."""
    rng = np.random.default_rng(seed)
    w, h = spec.size_m()
    centre_B = np.array([w / 2, h / 2, 0.0])
    K_inv = np.linalg.inv(intrinsics.camera_matrix())
    views: list[RigidTransform] = []
    attempts = 0
    while len(views) < count:
        attempts += 1
        if attempts > 200 * count:
            raise ConfigurationError(
                f"cannot place the {w:.3f} x {h:.3f} m board in view at {distance_m} m"
            )
        tilt = np.radians(rng.uniform(-max_tilt_deg, max_tilt_deg, 2))
        roll = np.radians(rng.uniform(-30, 30))
        distance = rng.uniform(*distance_m)
        # Camera facing the board (its z along z_B), rotated by the tilts and the roll.
        R_BC0 = RotationMatrix(RollPitchYaw(tilt[0], tilt[1], roll))
        p_BC = centre_B - distance * R_BC0.col(2)
        # Turn the camera about its centre so the board's centre lands on an image point.
        fraction = rng.uniform(0.0, 0.42, 2) * rng.choice([-1, 1], 2)
        pixel = np.array(
            [(0.5 + fraction[0]) * intrinsics.width, (0.5 + fraction[1]) * intrinsics.height, 1]
        )
        ray = K_inv @ pixel
        R_C0C = _RotationTaking(ray / np.linalg.norm(ray), np.array([0.0, 0.0, 1.0]))
        X_BC = RigidTransform(R_BC0 @ R_C0C, p_BC)
        if BoardCornersInView(spec, intrinsics, X_BC.inverse()):
            views.append(X_BC)
    return views
