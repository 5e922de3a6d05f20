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
    HandEyeFromImages,
    ReadPoses,
    WriteHandEye,
)
from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell, SimulatedView
from guidedarm.systems.calibration.camera_calibration_math import CameraCalibration
from guidedarm.systems.calibration.hand_eye_math import HandEyeResult


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
    """Calibrates the camera's mount into out_dir/hand_eye.yaml with the estimator's camera
    model; returns the result and the lines comparing it with the truth."""
    folder = TakePhotos(cell, out_dir, count, seed)
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    poses = ReadPoses(out_dir / "poses.csv")
    result, rejected = HandEyeFromImages(images, poses, cell.spec, cell.estimator_intrinsics)
    WriteHandEye(out_dir, result, rejected, cell.mount_frame)
    lines = [f"method {result.method} (scatter of the implied board poses, mm and deg):"]
    lines += [f"  {n:10s} {p:8.3f} {r:8.4f}" for n, (p, r) in result.scatter.items()]
    lines += PoseComparison(result.X_FC, cell.true_X_FC)
    return result, lines


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
