"""How far a PnP pose can be trusted: its standard deviations and a check of the camera
model against the image.

Standard deviations: the corner residuals r (2N values) at the optimum give the corner
noise s^2 = |r|^2 / (2N - 6); the pose's covariance is s^2 (J^T J)^-1 with J the Jacobian of
the projected corners by the rotation vector and the translation (cv2.projectPoints).
Reported per axis of the camera frame C: the position of P (mm) and the rotation vector's
components (deg, for small errors the rotation about C's axes).

Model check: a lens whose radial distortion the camera file does not describe bends the
corners' positions more the farther they lie from the principal point; the pose absorbs
part of it (a tilted, shifted panel) and hides the rest in residuals that look small
(1.3 px for a pose 8 deg off). So the pose and the first radial coefficient k1 are fitted
together to the same corners (cv2.calibrateCameraExtended, every other intrinsic fixed to
the file's): when the fitted k1 differs from the file's by more than MODEL_CHECK_SIGMAS of
its standard deviation, and the residual it explains (the RMS of what the fit with k1
removes from the corners' residuals, sqrt(rms_pose^2 - rms_with_k1^2)) exceeds
MODEL_CHECK_MIN_PX, the file does not fit the image. It needs two markers (8 corners).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# A k1 off by 0.25 gives |z| = 11 to 37 on the panel's views; the right model up to 7 on
# frontal views (where k1 trades with the tilt), which MODEL_CHECK_MIN_PX then clears.
MODEL_CHECK_SIGMAS = 5.0
# Residuals the fitted k1 explains below this are too small to matter to the pose: a clean
# view of the right model explains < 0.1 px, a k1 off by 0.25 explains 0.5 to 2.3 px
# (120 views of the marker studies, clean and degraded, docs/calibration.md).
MODEL_CHECK_MIN_PX = 0.25
MIN_CORNERS_FOR_MODEL_CHECK = 8


@dataclass
class ModelCheck:
    """The k1 the corners ask for (fitted_k1 +- fitted_k1_std) beside the file's (file_k1),
    the RMS residual that fitting k1 explains (px), and `fits`."""

    fitted_k1: float
    fitted_k1_std: float
    file_k1: float
    explained_px: float
    fits: bool

    def Why(self) -> str:
        """A sentence saying why the model does not fit ('' when it does)."""
        if self.fits:
            return ""
        return (
            f"the corners ask for k1 = {self.fitted_k1:.3f} +- {self.fitted_k1_std:.3f}, the "
            f"camera file has {self.file_k1:.3f} (explaining {self.explained_px:.2f} px of "
            "the corners' residuals): the camera model does not fit the image "
            "(guidedarm calibrate camera)"
        )


def PoseStdDevs(
    points: np.ndarray, pixels: np.ndarray, rvec, tvec, K: np.ndarray, dist: np.ndarray
) -> tuple[list[float], list[float]]:
    """(std of p_CP along C's x y z in mm, std of the rotation vector's components in deg)
    of the pose rvec, tvec fitted to `points` (N x 3) seen at `pixels` (N x 2); infinite
    when the corners do not determine the pose."""
    projected, jacobian = cv2.projectPoints(points, rvec, tvec, K, dist)
    residuals = (projected.reshape(-1, 2) - pixels).ravel()
    dof = residuals.size - 6
    J = jacobian[:, :6]
    information = J.T @ J
    if dof <= 0 or np.linalg.cond(information) > 1e12:
        return [float("inf")] * 3, [float("inf")] * 3
    variance = residuals @ residuals / dof
    std = np.sqrt(np.maximum(np.diag(np.linalg.inv(information)) * variance, 0.0))
    return (std[3:] * 1e3).tolist(), np.degrees(std[:3]).tolist()


def CheckRadialModel(
    points: np.ndarray, pixels: np.ndarray, rvec, tvec, K: np.ndarray, dist: np.ndarray, size
) -> ModelCheck | None:
    """The model check of the module docstring for a pose rvec, tvec of `points` seen at
    `pixels` by a width x height (`size`) camera K, dist; None with fewer than
    MIN_CORNERS_FOR_MODEL_CHECK corners or when OpenCV cannot fit them."""
    if len(points) < MIN_CORNERS_FOR_MODEL_CHECK:
        return None
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_FOCAL_LENGTH
        | cv2.CALIB_FIX_PRINCIPAL_POINT
        | cv2.CALIB_FIX_ASPECT_RATIO
        | cv2.CALIB_FIX_TANGENT_DIST
        | cv2.CALIB_FIX_K2
        | cv2.CALIB_FIX_K3
    )
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    try:
        rms_k1, _, fitted, _, _, std, _, _ = cv2.calibrateCameraExtended(
            [points.astype(np.float32)],
            [pixels.astype(np.float32).reshape(-1, 1, 2)],
            tuple(size),
            K.copy(),
            dist.reshape(1, -1).copy(),
            [np.array(rvec, float).reshape(3, 1)],  # copies: OpenCV writes its fit here
            [np.array(tvec, float).reshape(3, 1)],
            flags=flags | cv2.CALIB_USE_EXTRINSIC_GUESS,
            criteria=criteria,
        )
    except cv2.error:
        return None
    k1, k1_std = float(fitted.ravel()[0]), float(std.ravel()[4])
    if not (np.isfinite(k1) and np.isfinite(k1_std)):
        return None
    projected, _ = cv2.projectPoints(points, rvec, tvec, K, dist)
    rms_pose = np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - pixels) ** 2, axis=1)))
    explained = float(np.sqrt(max(rms_pose**2 - rms_k1**2, 0.0)))
    significant = abs(k1 - dist[0]) > MODEL_CHECK_SIGMAS * k1_std
    fits = not (significant and explained > MODEL_CHECK_MIN_PX)
    return ModelCheck(k1, k1_std, float(dist[0]), explained, fits)
