"""Kinematic calibration of an eye-in-hand arm: its joint offsets, the camera's mount, the
camera's focal length and the board's pose, fitted together to the board corners of all
views (a bundle adjustment).

Frames: W the arm's base (world), F the frame the camera is mounted on (on the arm's last
link), C the camera's optical frame, B the board (fixed in W). A view i holds the measured
joints q_i (rad), the board corners p_B (m) and where they were seen (px). The model:

    X_CB_i = (X_WF(q_i + delta - c tau_i) X_FC)^-1 X_WB,   pixels = project_s(X_CB_i p_B)

with delta the joint offsets (the true joint angle minus the measured one, rad), c the
joints' compliance (rad per N m: a harmonic drive's link sags under the gravity torque tau_i
it holds, while the encoder reads the motor side), X_WF the arm's forward kinematics on its
nominal model, and project_s the camera calibration's model with both focal lengths scaled
by (1 + s). The unknowns are delta and c of the identifiable joints, s, X_FC and X_WB; the
residual is the corners' reprojection error (px), minimised by Levenberg-Marquardt with a
finite-difference Jacobian (numpy only). Without the torques (or with the compliance left
out) the offsets absorb the views' mean sag and the mount the rest.

Why the focal scale: in every view of a board the focal length and the board's distance
trade (the image scales with f / distance); the camera calibration separates them only by
the foreshortening of tilted views, which leaves its focal length off by up to about 0.2 %,
and with f fixed the fit moves the mount along the optical axis by that fraction of the
views' distance (0.6 mm at 370 mm). Here the arm's kinematics tie the views together: the
camera moves by known amounts towards and away from the board, so the scale and the mount's
depth are determined separately (the scale then rests on the lengths of the arm's model, as
the joint offsets do). The principal point is not fitted: its error trades with the mount's
rotation in every view alike, which the arm does not separate either.

Gauge freedoms: the first joint's offset turns the whole arm about that joint's axis, fixed
in W, which a turn of the board about the same axis explains exactly; the last joint's
offset turns F about the last joint's axis, which a turn of the mount X_FC explains exactly.
Neither is identifiable: both stay 0, and the fitted X_FC is the camera's pose in the frame
F computed from the *measured* last joint (the one the controller needs, since it computes
F the same way), X_WB the board's pose in the frame W of the measured first joint.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.calibration.calibration_views import ProjectPoints
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

# Finite-difference step of the Jacobian (rad for angles, m for translations).
_STEP = 1e-6
_MAX_ITERATIONS = 50
# Where x holds the focal scale: before the 12 coordinates of X_FC's and X_WB's perturbations.
_SCALE = -13


@dataclass
class JointView:
    """One view: the measured joints q (rad), board corners points_B (N x 3, m) seen at
    pixels (N x 2, px), and the gravity torque each joint holds there (N m; None: the
    compliance is not fitted)."""

    q: np.ndarray
    points_B: np.ndarray
    pixels: np.ndarray
    holding_torque: np.ndarray | None = None


@dataclass
class KinematicCalibration:
    """The fit: joint_offset (rad per joint, 0 for the joints not identifiable), its standard
    deviation (rad, 0 where not fitted), joint_compliance (rad per N m, 0 where not fitted),
    X_FC, X_WB, the RMS reprojection error (px) and the largest view's RMS (px), the camera
    model with the fitted focal lengths (intrinsics) and the focal scale s with its standard
    deviation (dimensionless: fx and fy are the given ones times 1 + s)."""

    joint_offset: np.ndarray
    joint_offset_std: np.ndarray
    joint_compliance: np.ndarray
    X_FC: RigidTransform
    X_WB: RigidTransform
    rms_px: float
    worst_view_rms_px: float
    intrinsics: CameraIntrinsics
    focal_scale: float
    focal_scale_std: float


def IdentifiableJoints(num_joints: int) -> list[int]:
    """Indices of the joints whose offsets the views determine: all but the first and the
    last (the gauge freedoms, see the module docstring)."""
    if num_joints < 3:
        raise ConfigurationError(
            f"a kinematic calibration needs an arm of at least 3 joints, got {num_joints}"
        )
    return list(range(1, num_joints - 1))


def ViewsNeeded(num_joints: int, with_compliance: bool) -> int:
    """The fewest views CalibrateJoints takes: one per joint parameter, and 3 more (each
    view fixes the camera's 6 pose coordinates, the mount and the board take 12)."""
    return len(IdentifiableJoints(num_joints)) * (2 if with_compliance else 1) + 3


def _Perturbed(X: RigidTransform, d: np.ndarray) -> RigidTransform:
    """X moved by d = [rotation vector (rad), translation (m)], both in X's own frame."""
    return X @ RigidTransform(RotationMatrix(cv2.Rodrigues(d[:3])[0]), d[3:])


def ScaledFocalLength(intrinsics: CameraIntrinsics, scale: float) -> CameraIntrinsics:
    """`intrinsics` with fx and fy multiplied by 1 + scale (the rest unchanged)."""
    return dataclasses.replace(
        intrinsics, fx=intrinsics.fx * (1 + scale), fy=intrinsics.fy * (1 + scale)
    )


class _Problem:
    """x = [offsets of `joints`, compliances of `joints` (if fitted), the focal scale, X_FC's
    and X_WB's perturbations]."""

    def __init__(self, X_WF, views, intrinsics, joints):
        self.X_WF, self.views, self.joints = X_WF, views, joints
        self.intrinsics = intrinsics
        self.n = views[0].q.size
        self.compliant = views[0].holding_torque is not None
        self.size = len(joints) * (2 if self.compliant else 1) - _SCALE

    def Unpack(self, x, X_FC, X_WB):
        k = len(self.joints)
        delta, compliance = np.zeros(self.n), np.zeros(self.n)
        delta[self.joints] = x[:k]
        if self.compliant:
            compliance[self.joints] = x[k : 2 * k]
        pose = x[-12:]
        return delta, compliance, _Perturbed(X_FC, pose[:6]), _Perturbed(X_WB, pose[6:])

    def Residuals(self, x, X_FC, X_WB, per_view: bool = False):
        delta, compliance, X_FC, X_WB = self.Unpack(x, X_FC, X_WB)
        intrinsics = ScaledFocalLength(self.intrinsics, x[_SCALE])
        out = []
        for view in self.views:
            q = view.q + delta
            if self.compliant:
                q = q - compliance * view.holding_torque
            X_CB = (self.X_WF(q) @ X_FC).inverse() @ X_WB
            projected = ProjectPoints(intrinsics, X_CB, view.points_B)
            out.append((projected - view.pixels).ravel())
        return out if per_view else np.concatenate(out)


def CalibrateJoints(
    X_WF: Callable[[np.ndarray], RigidTransform],
    views: list[JointView],
    intrinsics: CameraIntrinsics,
    X_FC_seed: RigidTransform,
    X_WB_seed: RigidTransform,
) -> KinematicCalibration:
    """The joint offsets (and compliances, when the views hold their torques), the focal
    scale, X_FC and X_WB that best explain the views' corners (see the module docstring),
    from a seed (e.g. the hand-eye solution and the board pose it implies in one view) and
    the camera calibration's `intrinsics`.
    X_WF(q): the mount frame's pose on the arm's nominal model at joints q (rad)."""
    n = views[0].q.size
    joints = IdentifiableJoints(n)
    problem = _Problem(X_WF, views, intrinsics, joints)
    unknowns = problem.size
    needed = ViewsNeeded(n, problem.compliant)
    if len(views) < needed:
        raise ConfigurationError(
            f"{len(views)} views for a kinematic calibration of {unknowns + _SCALE} joint "
            f"parameters, at least {needed} needed"
        )
    x = np.zeros(unknowns)
    residual = problem.Residuals(x, X_FC_seed, X_WB_seed)
    cost, damping = residual @ residual, 1e-3
    for _ in range(_MAX_ITERATIONS):
        J = _Jacobian(problem, x, residual, X_FC_seed, X_WB_seed)
        H, g = J.T @ J, J.T @ residual
        step = np.linalg.solve(H + damping * np.diag(np.diag(H) + 1e-12), -g)
        trial = problem.Residuals(x + step, X_FC_seed, X_WB_seed)
        if trial @ trial < cost:
            improvement = (cost - trial @ trial) / cost
            x, residual, cost = x + step, trial, trial @ trial
            damping = max(damping / 10, 1e-9)
            if improvement < 1e-10:
                break
        else:
            damping *= 10
            if damping > 1e8:
                break
    J = _Jacobian(problem, x, residual, X_FC_seed, X_WB_seed)
    variance = cost / max(residual.size - unknowns, 1)
    covariance = variance * np.linalg.pinv(J.T @ J)
    delta, compliance, X_FC, X_WB = problem.Unpack(x, X_FC_seed, X_WB_seed)
    std = np.zeros(n)
    std[joints] = np.sqrt(np.diag(covariance)[: len(joints)])
    per_view = problem.Residuals(x, X_FC_seed, X_WB_seed, per_view=True)
    return KinematicCalibration(
        delta,
        std,
        compliance,
        X_FC,
        X_WB,
        float(np.sqrt(np.mean(residual**2) * 2)),
        float(max(np.sqrt(np.mean(r**2) * 2) for r in per_view)),
        ScaledFocalLength(intrinsics, x[_SCALE]),
        float(x[_SCALE]),
        float(np.sqrt(covariance[_SCALE, _SCALE])),
    )


def _Jacobian(problem: _Problem, x, residual, X_FC, X_WB) -> np.ndarray:
    J = np.empty((residual.size, x.size))
    for k in range(x.size):
        dx = np.zeros_like(x)
        dx[k] = _STEP
        J[:, k] = (problem.Residuals(x + dx, X_FC, X_WB) - residual) / _STEP
    return J
