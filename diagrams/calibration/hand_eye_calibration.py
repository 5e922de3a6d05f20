"""`guidedarm calibrate hand-eye --images DIR --poses POSES.csv --board BOARD.yaml
--camera CAMERA.yaml --out OUT`: the camera's pose on the arm from recorded data.

POSES.csv: a header `image,x,y,z,roll_deg,pitch_deg,yaw_deg`, then one row per photo: the
photo's file name in DIR and the pose X_WF of the frame F the camera is mounted on (the
parent frame of the scenario's camera X_PB) in the arm's base frame W when the photo was
taken (m; Drake's roll-pitch-yaw in deg), as the arm's controller reports it. The board
stays fixed while the arm moves. OUT/hand_eye.yaml holds X_PC (C in F, a Drake schema
Transform) and a comment comparing OpenCV's methods; OUT/hand_eye_report.json the same
in numbers.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.calibration.calibration_files import TransformFileText
from guidedarm.systems.calibration.camera_calibration_math import BoardView, FindBoardView
from guidedarm.systems.calibration.charuco_board import BoardSpec, CharucoCornerDetector
from guidedarm.systems.calibration.hand_eye_math import (
    BoardPose,
    CalibrateHandEye,
    HandEyeResult,
)
from guidedarm.systems.calibration.joint_bundle_adjustment import KinematicCalibration
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

POSE_COLUMNS = ["image", "x", "y", "z", "roll_deg", "pitch_deg", "yaw_deg"]


def ReadPoses(path: Path) -> dict[str, RigidTransform]:
    """The X_WF of each image in a POSES.csv (see the module docstring)."""
    if not path.is_file():
        raise ConfigurationError(f"--poses {path}: file not found")
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows or [c.strip() for c in rows[0]] != POSE_COLUMNS:
        raise ConfigurationError(f"--poses {path}: the header must be {','.join(POSE_COLUMNS)}")
    poses = {}
    for line, row in enumerate(rows[1:], start=2):
        try:
            values = [float(v) for v in row[1:]]
        except ValueError:
            values = []
        if len(row) != 7 or not np.all(np.isfinite(values)) or len(values) != 6:
            raise ConfigurationError(
                f"--poses {path}, line {line}: expected an image name and 6 numbers"
            )
        if row[0] in poses:
            raise ConfigurationError(f"--poses {path}, line {line}: image {row[0]} appears twice")
        rpy = RollPitchYaw(np.radians(values[3:]))
        poses[row[0].strip()] = RigidTransform(rpy, values[:3])
    return poses


@dataclass
class HandEyeViews:
    """The usable views of a hand-eye data set: image names, X_WF, the board views (corners)
    and X_CB of each, and the images rejected with why."""

    names: list[str] = field(default_factory=list)
    X_WF: list[RigidTransform] = field(default_factory=list)
    views: list[BoardView] = field(default_factory=list)
    X_CB: list[RigidTransform] = field(default_factory=list)
    rejected: dict[str, str] = field(default_factory=dict)


def FindHandEyeViews(
    images: list[tuple[str, np.ndarray | None]],
    poses: dict[str, RigidTransform],
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
) -> HandEyeViews:
    """The board in each named BGR image (None: not an image) that has an X_WF in `poses`."""
    detector = CharucoCornerDetector(spec)
    found = HandEyeViews()
    for name, image in images:
        if image is None:
            found.rejected[name] = "not an image file"
            continue
        if name not in poses:
            found.rejected[name] = "no arm pose for it in the poses file"
            continue
        if (image.shape[1], image.shape[0]) != (intrinsics.width, intrinsics.height):
            found.rejected[name] = (
                f"{image.shape[1]} x {image.shape[0]} px, the camera file says "
                f"{intrinsics.width} x {intrinsics.height}"
            )
            continue
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        view = FindBoardView(detector, name, gray)
        if isinstance(view, str):
            found.rejected[name] = view
            continue
        found.names.append(name)
        found.X_WF.append(poses[name])
        found.views.append(view)
        found.X_CB.append(BoardPose(view.points_B, view.pixels, intrinsics))
    return found


def HandEyeFromImages(
    images: list[tuple[str, np.ndarray | None]],
    poses: dict[str, RigidTransform],
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
) -> tuple[HandEyeResult, dict[str, str]]:
    """The hand-eye fit from named BGR images (None: not an image) with their X_WF, and the
    images rejected with why."""
    found = FindHandEyeViews(images, poses, spec, intrinsics)
    return CalibrateHandEye(found.X_WF, found.X_CB), found.rejected


def WriteHandEye(
    out_dir: Path,
    result: HandEyeResult,
    rejected: dict[str, str],
    base_frame: str = "",
    joints: KinematicCalibration | None = None,
) -> Path:
    """Writes out_dir/hand_eye.yaml (X_PC, with base_frame when given) and
    out_dir/hand_eye_report.json; returns the YAML's path. joints: the kinematic calibration
    refining `result` (its X_FC is written, valid with its joint offsets)."""
    comments = [
        "The camera's optical frame C in the frame it is mounted on (`guidedarm calibrate",
        "hand-eye`): replaces the camera's X_PB (with X_BC identity).",
        f"Method {result.method}, chosen for the smallest scatter of the board poses it implies:",
    ]
    comments += [f"  {name}: {p:.3f} mm, {r:.4f} deg" for name, (p, r) in result.scatter.items()]
    X_PC = result.X_FC
    if joints is not None:
        X_PC = joints.X_FC
        comments += [
            "Refined with the arm's joint offsets (joint_offsets.yaml, use both) to the board's",
            f"corners: RMS {joints.rms_px:.3f} px, worst view {joints.worst_view_rms_px:.3f} px.",
        ]
    text = TransformFileText("X_PC", X_PC, comments)
    if base_frame:
        text += f"  base_frame: {base_frame}\n"
    path = out_dir / "hand_eye.yaml"
    path.write_text(text)
    report = {
        "method": result.method,
        "views_used": result.views,
        "scatter_mm_deg": {n: [round(p, 4), round(r, 5)] for n, (p, r) in result.scatter.items()},
        "X_PC_by_method": {
            n: X.GetAsMatrix34().round(6).tolist() for n, X in result.solutions.items()
        },
        "rejected": rejected,
    }
    if joints is not None:
        report["joint_calibration"] = {
            "X_PC": X_PC.GetAsMatrix34().round(6).tolist(),
            "joint_offset_rad": joints.joint_offset.round(6).tolist(),
            "joint_offset_std_rad": joints.joint_offset_std.round(7).tolist(),
            "joint_compliance_rad_per_N_m": joints.joint_compliance.tolist(),
            "rms_px": round(joints.rms_px, 4),
            "worst_view_rms_px": round(joints.worst_view_rms_px, 4),
        }
    (out_dir / "hand_eye_report.json").write_text(json.dumps(report, indent=1) + "\n")
    return path
