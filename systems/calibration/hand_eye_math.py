"""The camera's pose on the arm (hand-eye calibration, eye in hand) from arm poses and views
of a fixed board.

Frames: W the arm's base (world), F the frame the camera is mounted on (the parent frame of
the scenario's camera X_PB, e.g. `rover_gripper::camera`), C the camera's optical frame, B
the board (fixed in W). For every view i: X_WF_i (the arm's forward kinematics on its
measured joints) and X_CB_i (PnP of the board's corners) satisfy
X_WF_i X_FC X_CB_i = X_WB for one unknown X_FC and one unknown X_WB.

OpenCV's cv2.calibrateHandEye offers five solutions of AX = XB (Tsai-Lenz, Park-Martin,
Horaud, Andreff, Daniilidis); they weigh rotation and translation noise differently, and
which is best depends on the data. Each is scored here by how well it explains the data
without a ground truth: the board poses X_WB_i = X_WF_i X_FC X_CB_i it implies should
coincide; the method with the smallest scatter (RMS translation of X_WB_i about their mean,
plus the RMS rotation angle times SCATTER_LENGTH_M) is chosen.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

HAND_EYE_METHODS = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
# A rotation error of 1 rad counts as a translation error of this (m): the board's size.
SCATTER_LENGTH_M = 0.2
# Hand-eye needs rotations about at least two different axes between views.
MIN_HAND_EYE_VIEWS = 5


@dataclass
class HandEyeResult:
    """X_FC of the chosen method, its name, and every method's X_FC and scatter:
    (RMS translation of the implied board poses, mm; RMS rotation, deg)."""

    X_FC: RigidTransform
    method: str
    solutions: dict[str, RigidTransform]
    scatter: dict[str, tuple[float, float]]
    views: int


def BoardPose(
    points_B: np.ndarray, pixels: np.ndarray, intrinsics: CameraIntrinsics
) -> RigidTransform:
    """X_CB from board corners (N x 3, m) seen at pixels (N x 2): planar PnP (IPPE), then
    Levenberg-Marquardt refinement."""
    K, dist = intrinsics.camera_matrix(), intrinsics.distortion_vector()
    ok, rvec, tvec = cv2.solvePnP(points_B, pixels, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        raise ConfigurationError("the board's pose cannot be solved from its corners")
    rvec, tvec = cv2.solvePnPRefineLM(points_B, pixels, K, dist, rvec, tvec)
    return RigidTransform(RotationMatrix(cv2.Rodrigues(rvec)[0]), tvec.ravel())


def BoardScatter(
    X_WF: list[RigidTransform], X_FC: RigidTransform, X_CB: list[RigidTransform]
) -> tuple[float, float]:
    """(RMS distance of the implied board positions from their mean, mm; RMS angle of the
    implied board rotations from their mean, deg)."""
    poses = [a @ X_FC @ b for a, b in zip(X_WF, X_CB, strict=True)]
    p = np.array([X.translation() for X in poses])
    mean_R = _MeanRotation([X.rotation() for X in poses])
    angles = [(mean_R.inverse() @ X.rotation()).ToAngleAxis().angle() for X in poses]
    rms_p = np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1)))
    return float(rms_p * 1e3), float(np.degrees(np.sqrt(np.mean(np.square(angles)))))


def CalibrateHandEye(X_WF: list[RigidTransform], X_CB: list[RigidTransform]) -> HandEyeResult:
    """X_FC from pairs of arm poses and board poses (see the module docstring)."""
    if len(X_WF) != len(X_CB):
        raise ConfigurationError(f"{len(X_WF)} arm poses for {len(X_CB)} board views")
    if len(X_WF) < MIN_HAND_EYE_VIEWS:
        raise ConfigurationError(
            f"{len(X_WF)} views with an arm pose, at least {MIN_HAND_EYE_VIEWS} needed"
        )
    _CheckRotationsDiffer(X_WF)
    R_gripper = [X.rotation().matrix() for X in X_WF]
    t_gripper = [X.translation().reshape(3, 1) for X in X_WF]
    R_target = [X.rotation().matrix() for X in X_CB]
    t_target = [X.translation().reshape(3, 1) for X in X_CB]
    solutions, scatter = {}, {}
    for name, method in HAND_EYE_METHODS.items():
        try:
            R, t = cv2.calibrateHandEye(R_gripper, t_gripper, R_target, t_target, method=method)
        except cv2.error:
            continue
        if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
            continue
        X_FC = RigidTransform(RotationMatrix(_Orthonormal(R)), t.ravel())
        solutions[name] = X_FC
        scatter[name] = BoardScatter(X_WF, X_FC, X_CB)
    if not solutions:
        raise ConfigurationError("no hand-eye method found a solution for these views")
    best = min(scatter, key=lambda n: _ScatterScore(*scatter[n]))
    return HandEyeResult(solutions[best], best, solutions, scatter, len(X_WF))


def _ScatterScore(rms_mm: float, rms_deg: float) -> float:
    """One number (mm) for a scatter: rotation counted at SCATTER_LENGTH_M per radian."""
    return rms_mm + SCATTER_LENGTH_M * 1e3 * np.radians(rms_deg)


def _CheckRotationsDiffer(X_WF: list[RigidTransform]) -> None:
    """Refuses views whose arm rotations all turn about one axis (or not at all): X_FC's
    translation along that axis is then undetermined."""
    R0 = X_WF[0].rotation()
    axes = []
    for X in X_WF[1:]:
        angle_axis = (R0.inverse() @ X.rotation()).ToAngleAxis()
        if angle_axis.angle() > np.radians(2):
            axes.append(angle_axis.axis())
    if len(axes) < 2 or np.linalg.matrix_rank(np.array(axes), tol=0.1) < 2:
        raise ConfigurationError(
            "the arm poses turn about fewer than two different axes (at least 2 deg apart): "
            "tilt the camera about different axes between views"
        )


def _Orthonormal(R: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(R)
    return u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt


def _MeanRotation(rotations: list[RotationMatrix]) -> RotationMatrix:
    """The chordal mean (the rotation nearest the mean of the matrices)."""
    return RotationMatrix(_Orthonormal(np.mean([R.matrix() for R in rotations], axis=0)))
