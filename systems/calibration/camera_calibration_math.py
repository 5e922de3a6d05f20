"""Camera intrinsics and lens distortion from views of a ChArUco board (Zhang's method, as
OpenCV implements it).

Each view's inner corners (found by CharucoCornerDetector) are paired with their board
points (B frame, m); cv2.calibrateCameraExtended fits fx, fy, cx, cy, k1 k2 p1 p2 k3 and
one board pose per view, and returns the parameters' standard deviations (from the
Jacobian at the optimum, scaled by the residual). A view whose RMS reprojection error is
far above the others' (a misdetection, motion blur, another board) is rejected and the
fit repeated without it. Pixel coordinates are OpenCV's (pixel centres at integers).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.calibration.charuco_board import (
    MIN_CORNERS_PER_VIEW,
    CharucoCornerDetector,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

# Fewest accepted views: 9 parameters plus 6 per view need several views at different tilts.
MIN_VIEWS = 5
# A view is an outlier when its RMS error exceeds both this and OUTLIER_FACTOR x the median
# view's: sharp views of a flat board fit to ~0.1-0.3 px.
OUTLIER_FLOOR_PX = 1.0
OUTLIER_FACTOR = 3.0
# The fit is refused when even the median view fits worse than this: the board file does not
# describe the photographed board, or the lens is beyond the k1 k2 p1 p2 k3 model.
MAX_MEDIAN_VIEW_ERROR_PX = 2.0
INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


@dataclass
class BoardView:
    """The inner corners of the board found in one image: ids, pixels (N x 2) and their
    board points (N x 3, m, in B)."""

    name: str
    ids: np.ndarray
    pixels: np.ndarray
    points_B: np.ndarray


@dataclass
class CameraCalibration:
    """The fit: intrinsics, the standard deviation of each of INTRINSIC_NAMES (px, or
    unitless for distortion), the overall and per-view RMS reprojection errors (px), each
    view's board pose X_CB, and the views rejected with why."""

    intrinsics: CameraIntrinsics
    std_devs: dict[str, float]
    rms_px: float
    view_rms_px: dict[str, float]
    X_CB: dict[str, RigidTransform]
    rejected: dict[str, str] = field(default_factory=dict)


def FindBoardView(detector: CharucoCornerDetector, name: str, gray: np.ndarray) -> BoardView | str:
    """The board view in a greyscale image, or why there is none usable (a sentence)."""
    ids, pixels, markers = detector.Detect(gray)
    if markers == 0:
        return f"no marker of the board ({detector.spec.dictionary}) in view"
    if len(ids) == 0:
        return (
            f"{markers} markers of {detector.spec.dictionary} seen, but none where the board "
            "file puts them (another layout: squares_x, squares_y?)"
        )
    if len(ids) < MIN_CORNERS_PER_VIEW:
        return f"{len(ids)} board corners found, at least {MIN_CORNERS_PER_VIEW} needed"
    points_B = detector.CornerPoints_B(ids)
    # Corners on one line give no homography: the view says nothing about the focal length.
    spread = np.linalg.svd(points_B[:, :2] - points_B[:, :2].mean(axis=0), compute_uv=False)
    if spread[1] < 0.5 * detector.spec.square_m:
        return "the corners found lie on one line"
    return BoardView(name, ids, pixels, points_B)


def CalibrateCamera(
    views: list[BoardView], width: int, height: int, rejected: dict[str, str] | None = None
) -> CameraCalibration:
    """Fits the intrinsics to `views` of a width x height px camera (see the module
    docstring); `rejected` (name -> why) is carried into the result and extended with the
    outliers. Raises ConfigurationError when fewer than MIN_VIEWS views remain or the fit
    is poor."""
    rejected = dict(rejected or {})
    views = list(views)
    while True:
        _CheckViewCount(views, rejected)
        fit = _Fit(views, width, height)
        errors = fit.view_rms_px
        median = float(np.median(list(errors.values())))
        if median > MAX_MEDIAN_VIEW_ERROR_PX:
            raise ConfigurationError(
                f"the median view fits to {median:.2f} px (more than "
                f"{MAX_MEDIAN_VIEW_ERROR_PX} px): the board file does not describe the "
                "photographed board, or the lens is beyond the k1 k2 p1 p2 k3 model"
            )
        limit = max(OUTLIER_FLOOR_PX, OUTLIER_FACTOR * median)
        worst = max(errors, key=errors.get)
        if errors[worst] <= limit:
            fit.rejected = rejected
            return fit
        rejected[worst] = (
            f"reprojection error {errors[worst]:.2f} px, more than {limit:.2f} px "
            "(a misdetection or a blurred view)"
        )
        views = [v for v in views if v.name != worst]


def _CheckViewCount(views: list[BoardView], rejected: dict[str, str]) -> None:
    if len(views) < MIN_VIEWS:
        raise ConfigurationError(
            f"{len(views)} usable views of the board, at least {MIN_VIEWS} needed "
            f"({len(rejected)} rejected)"
        )


def _Fit(views: list[BoardView], width: int, height: int) -> CameraCalibration:
    object_points = [v.points_B.astype(np.float32) for v in views]
    image_points = [v.pixels.astype(np.float32).reshape(-1, 1, 2) for v in views]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        rms, K, dist, rvecs, tvecs, std_intrinsics, _, view_errors = cv2.calibrateCameraExtended(
            object_points, image_points, (width, height), None, None, criteria=criteria
        )
    except cv2.error as e:
        raise ConfigurationError(f"OpenCV cannot fit these views: {e.err}") from None
    dist = dist.ravel()[:5]
    intrinsics = CameraIntrinsics(
        width=width,
        height=height,
        fx=float(K[0, 0]),
        fy=float(K[1, 1]),
        cx=float(K[0, 2]),
        cy=float(K[1, 2]),
        distortion=[float(d) for d in dist],
    )
    names = [v.name for v in views]
    X_CB = {
        n: RigidTransform(RotationMatrix(cv2.Rodrigues(r)[0]), t.ravel())
        for n, r, t in zip(names, rvecs, tvecs, strict=True)
    }
    return CameraCalibration(
        intrinsics=intrinsics,
        std_devs=dict(zip(INTRINSIC_NAMES, map(float, std_intrinsics.ravel()[:9]), strict=True)),
        rms_px=float(rms),
        view_rms_px=dict(zip(names, map(float, view_errors.ravel()), strict=True)),
        X_CB=X_CB,
    )
