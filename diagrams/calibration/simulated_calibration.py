"""`guidedarm calibrate camera | hand-eye SCENARIO --out DIR`: the calibrations in simulation.

The simulated cell (simulated_cell.py) takes the photos and records the arm poses as a real
cell would, into DIR/images/ and DIR/poses.csv (the offline commands' input format); the
offline calibration then runs on them, and its result is printed beside the truth of the
simulated cell (the camera the station renders with, the camera's true mount) and the
residual error.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.calibration.camera_calibration import CalibrateCameraFromImages
from guidedarm.diagrams.calibration.hand_eye_calibration import (
    POSE_COLUMNS,
    FindHandEyeViews,
    ReadPoses,
    WriteHandEye,
)
from guidedarm.diagrams.calibration.hand_eye_joints import (
    CalibrateArmAndMount,
    ReadJoints,
    WriteHandEyeCamera,
    WriteJointOffsets,
    WriteJoints,
)
from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell, SimulatedView
from guidedarm.systems.calibration.camera_calibration_math import CameraCalibration
from guidedarm.systems.calibration.hand_eye_math import CalibrateHandEye, HandEyeResult
from guidedarm.systems.calibration.joint_bundle_adjustment import (
    IdentifiableJoints,
    KinematicCalibration,
    ViewsNeeded,
)
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics


def TakePhotos(cell: SimulatedCalibrationCell, out_dir: Path, count: int, seed: int) -> Path:
    """Writes the views to out_dir/images/viewNN.png and out_dir/poses.csv; returns the
    images folder."""
    views: list[SimulatedView] = cell.Photos(count, seed)
    folder = out_dir / "images"
    folder.mkdir(parents=True, exist_ok=True)
    rows = [",".join(POSE_COLUMNS)]
    for view in views:
        cv2.imwrite(str(folder / f"{view.name}.png"), cv2.cvtColor(view.image, cv2.COLOR_RGBA2BGR))
        rpy = np.degrees(RollPitchYaw(view.X_WF.rotation()).vector())
        values = [*view.X_WF.translation(), *rpy]
        rows.append(f"{view.name}.png," + ",".join(f"{v:.9g}" for v in values))
    (out_dir / "poses.csv").write_text("\n".join(rows) + "\n")
    WriteJoints(out_dir / "joints.csv", [(f"{v.name}.png", v.q_measured) for v in views])
    return folder


def CameraInSimulation(
    cell: SimulatedCalibrationCell, out_dir: Path, count: int, seed: int
) -> tuple[CameraCalibration, list[str]]:
    """Calibrates the simulated camera into out_dir/camera.yaml; returns the calibration
    and the lines comparing it with the truth."""
    folder = TakePhotos(cell, out_dir, count, seed)
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    calibration = CalibrateCameraFromImages(images, cell.spec, out_dir / "camera.yaml", str(folder))
    truth = cell.true_intrinsics
    fit = calibration.intrinsics
    lines = [f"{'':4s} {'calibrated':>12s} {'truth':>12s} {'residual':>10s}  (std dev)"]
    for name in ("fx", "fy", "cx", "cy"):
        a, b = getattr(fit, name), getattr(truth, name)
        lines.append(
            f"{name:4s} {a:12.3f} {b:12.3f} {a - b:10.3f}  ({calibration.std_devs[name]:.3f}) px"
        )
    for i, name in enumerate(("k1", "k2", "p1", "p2", "k3")):
        a, b = fit.distortion[i], truth.distortion[i]
        lines.append(
            f"{name:4s} {a:12.5f} {b:12.5f} {a - b:10.5f}  ({calibration.std_devs[name]:.5f})"
        )
    return calibration, lines


def HandEyeInSimulation(
    cell: SimulatedCalibrationCell, out_dir: Path, count: int, seed: int
) -> tuple[HandEyeResult, list[str]]:
    """Calibrates the camera's mount, the arm's joint offsets and the focal length into
    out_dir/hand_eye.yaml, joint_offsets.yaml and hand_eye_camera.yaml, starting from the
    estimator's camera model; returns the hand-eye seed and the lines comparing the result
    with the truth."""
    folder = TakePhotos(cell, out_dir, count, seed)
    source = cell.scenario.estimator_camera_file or f"camera '{cell.scenario.camera}'"
    return HandEyeFromFolder(cell, out_dir, folder, cell.estimator_intrinsics, source)


def HandEyeFromFolder(
    cell: SimulatedCalibrationCell,
    out_dir: Path,
    folder: Path,
    intrinsics: CameraIntrinsics,
    camera_source: str,
) -> tuple[HandEyeResult, list[str]]:
    """HandEyeInSimulation on photos already taken (folder, out_dir/poses.csv and
    out_dir/joints.csv) with the camera model `intrinsics` (camera_source names it in
    hand_eye_camera.yaml)."""
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    found = FindHandEyeViews(images, ReadPoses(out_dir / "poses.csv"), cell.spec, intrinsics)
    result = CalibrateHandEye(found.X_WF, found.X_CB)
    lines = [f"method {result.method} (scatter of the implied board poses, mm and deg):"]
    lines += [f"  {n:10s} {p:8.3f} {r:8.4f}" for n, (p, r) in result.scatter.items()]
    lines.append(f"hand-eye alone ({result.method}), against the true mount:")
    lines += PoseComparison(result.X_FC, cell.true_X_FC)
    needed = ViewsNeeded(cell.kinematics.plant.num_positions(), with_compliance=True)
    if len(found.names) < needed:
        WriteHandEye(out_dir, result, found.rejected, cell.mount_frame)
        lines.append(
            f"{len(found.names)} views: too few for the arm's joint offsets and compliance "
            f"(at least {needed}); hand_eye.yaml holds the hand-eye alone"
        )
        return result, lines
    joints = CalibrateArmAndMount(
        found,
        ReadJoints(out_dir / "joints.csv"),
        cell.X_WF,
        intrinsics,
        result,
        cell.HoldingTorque,
    )
    WriteHandEye(out_dir, result, found.rejected, cell.mount_frame, joints)
    path = WriteJointOffsets(out_dir, joints, cell.scenario.arm)
    camera = WriteHandEyeCamera(out_dir, joints, camera_source)
    lines.append(
        f"wrote {path} and {camera}: joint offsets, focal length and mount fitted to the "
        f"corners, RMS {joints.rms_px:.3f} px (worst view {joints.worst_view_rms_px:.3f} px)"
    )
    lines += JointOffsetComparison(joints, cell.true_joint_offset, cell.true_joint_stiffness)
    lines += FocalComparison(joints, intrinsics, cell.true_intrinsics)
    lines.append("the mount with the joint offsets, against the true mount in the measured flange:")
    lines += PoseComparison(joints.X_FC, cell.TrueMountInMeasuredFlange())
    return result, lines


def FocalComparison(
    joints: KinematicCalibration, given: CameraIntrinsics, truth: CameraIntrinsics
) -> list[str]:
    """Lines: the focal lengths (px) given to the fit, fitted with the arm, and the truth."""
    lines = [f"  {'':4s} {'given':>10s} {'fitted':>10s} {'truth':>10s} px"]
    for name in ("fx", "fy"):
        values = [getattr(c, name) for c in (given, joints.intrinsics, truth)]
        lines.append(f"  {name:4s} " + " ".join(f"{v:10.3f}" for v in values))
    return lines


def JointOffsetComparison(
    joints: KinematicCalibration, truth: np.ndarray, stiffness: np.ndarray
) -> list[str]:
    """Lines: each joint's identified offset, the truth and the residual (mrad), and its
    stiffness (1 / the identified compliance) beside the true one (N m/rad; inf: rigid)."""
    fitted = IdentifiableJoints(truth.size)
    lines = [
        f"  {'joint':5s} {'calibrated':>10s} {'truth':>9s} {'residual':>9s} (std) mrad"
        "   stiffness calibrated, truth (N m/rad)"
    ]
    for i, (value, true) in enumerate(zip(joints.joint_offset, truth, strict=True)):
        if i not in fitted:
            lines.append(f"  {i + 1:<5d} {'-':>10s} {true * 1e3:9.3f}  not identifiable")
            continue
        compliance = joints.joint_compliance[i]
        fitted_k = f"{1 / compliance:9.0f}" if compliance > 0 else "      inf"
        lines.append(
            f"  {i + 1:<5d} {value * 1e3:10.3f} {true * 1e3:9.3f} {(value - true) * 1e3:9.3f}"
            f" ({joints.joint_offset_std[i] * 1e3:.3f})   {fitted_k} {stiffness[i]:9.0f}"
        )
    return lines


def PoseComparison(estimate: RigidTransform, truth: RigidTransform) -> list[str]:
    """Lines: translation (mm) and roll-pitch-yaw (deg) of both, and the residual."""
    error = truth.inverse() @ estimate
    lines = []
    for label, X in (("calibrated", estimate), ("truth", truth)):
        p = X.translation() * 1e3
        rpy = np.degrees(RollPitchYaw(X.rotation()).vector())
        xyz = " ".join(f"{v:9.3f}" for v in p)
        angles = " ".join(f"{v:9.4f}" for v in rpy)
        lines.append(f"  X_PC {label:10s} p [{xyz}] mm, rpy [{angles}] deg")
    angle = np.degrees(error.rotation().ToAngleAxis().angle())
    lines.append(
        f"  residual   {np.linalg.norm(error.translation()) * 1e3:.3f} mm, {angle:.4f} deg"
    )
    return lines
