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
from pathlib import Path

import cv2
import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.calibration.calibration_files import TransformFileText
from guidedarm.systems.calibration.camera_calibration_math import FindBoardView
from guidedarm.systems.calibration.charuco_board import BoardSpec, CharucoCornerDetector
from guidedarm.systems.calibration.hand_eye_math import (
    BoardPose,
    CalibrateHandEye,
    HandEyeResult,
)
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


def HandEyeFromImages(
    images: list[tuple[str, np.ndarray | None]],
    poses: dict[str, RigidTransform],
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
) -> tuple[HandEyeResult, dict[str, str]]:
    """The hand-eye fit from named BGR images (None: not an image) with their X_WF, and the
    images rejected with why."""
    detector = CharucoCornerDetector(spec)
    X_WF, X_CB, rejected = [], [], {}
    for name, image in images:
        if image is None:
            rejected[name] = "not an image file"
            continue
        if name not in poses:
            rejected[name] = "no arm pose for it in the poses file"
            continue
        if (image.shape[1], image.shape[0]) != (intrinsics.width, intrinsics.height):
            rejected[name] = (
                f"{image.shape[1]} x {image.shape[0]} px, the camera file says "
                f"{intrinsics.width} x {intrinsics.height}"
            )
            continue
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        view = FindBoardView(detector, name, gray)
        if isinstance(view, str):
            rejected[name] = view
            continue
        X_WF.append(poses[name])
        X_CB.append(BoardPose(view.points_B, view.pixels, intrinsics))
    return CalibrateHandEye(X_WF, X_CB), rejected


def WriteHandEye(
    out_dir: Path, result: HandEyeResult, rejected: dict[str, str], base_frame: str = ""
) -> Path:
    """Writes out_dir/hand_eye.yaml (X_PC, with base_frame when given) and
    out_dir/hand_eye_report.json; returns the YAML's path."""
    comments = [
        "The camera's optical frame C in the frame it is mounted on (`guidedarm calibrate",
        "hand-eye`): replaces the camera's X_PB (with X_BC identity).",
        f"Method {result.method}, chosen for the smallest scatter of the board poses it implies:",
    ]
    comments += [f"  {name}: {p:.3f} mm, {r:.4f} deg" for name, (p, r) in result.scatter.items()]
    text = TransformFileText("X_PC", result.X_FC, comments)
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
    (out_dir / "hand_eye_report.json").write_text(json.dumps(report, indent=1) + "\n")
    return path
