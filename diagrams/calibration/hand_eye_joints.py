"""The hand-eye calibration with the arm's joint offsets: the measured joints of every photo
(JOINTS.csv), the kinematic calibration (systems/calibration/joint_bundle_adjustment.py)
seeded by OpenCV's hand-eye solution, DIR/joint_offsets.yaml, which the arm's
`calibration_file` takes, and DIR/hand_eye_camera.yaml, the camera file with the focal
lengths fitted with the arm, which the estimator takes with the mount.

JOINTS.csv: a header `image,q1,...,qn`, then one row per photo: its file name and the arm's
measured joint positions (rad) when it was taken.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.diagrams.calibration.calibration_files import CameraFileText
from guidedarm.diagrams.calibration.hand_eye_calibration import HandEyeViews
from guidedarm.systems.calibration.hand_eye_math import HandEyeResult
from guidedarm.systems.calibration.joint_bundle_adjustment import (
    CalibrateJoints,
    IdentifiableJoints,
    JointView,
    KinematicCalibration,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics


def WriteJoints(path: Path, rows: list[tuple[str, np.ndarray]]) -> None:
    """JOINTS.csv from (image name, measured joints in rad) rows."""
    n = rows[0][1].size
    lines = [",".join(["image"] + [f"q{i + 1}" for i in range(n)])]
    lines += [f"{name}," + ",".join(f"{v:.9g}" for v in q) for name, q in rows]
    path.write_text("\n".join(lines) + "\n")


def ReadJoints(path: Path) -> dict[str, np.ndarray]:
    """The measured joints (rad) of each image in a JOINTS.csv (see the module docstring)."""
    if not path.is_file():
        raise ConfigurationError(f"{path}: file not found")
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows or rows[0][0].strip() != "image" or len(rows[0]) < 4:
        raise ConfigurationError(f"{path}: the header must be image,q1,...,qn")
    joints = {}
    for line, row in enumerate(rows[1:], start=2):
        try:
            q = np.array([float(v) for v in row[1:]])
        except ValueError:
            q = np.array([])
        if q.size != len(rows[0]) - 1 or not np.all(np.isfinite(q)):
            raise ConfigurationError(
                f"{path}, line {line}: expected an image name and {len(rows[0]) - 1} numbers"
            )
        joints[row[0].strip()] = q
    return joints


def CalibrateArmAndMount(
    found: HandEyeViews,
    joints: dict[str, np.ndarray],
    X_WF: Callable[[np.ndarray], RigidTransform],
    intrinsics: CameraIntrinsics,
    seed: HandEyeResult,
    holding_torque: Callable[[np.ndarray], np.ndarray] | None = None,
) -> KinematicCalibration:
    """The joint offsets and the mount from the views `found` (their measured joints in
    `joints`), seeded by the hand-eye solution `seed`. X_WF(q): the mount frame's pose on
    the arm's nominal model (m) at joints q (rad); holding_torque(q): the gravity torque
    (N m) each joint holds at q, to fit the joints' compliance too (None: rigid)."""
    missing = [n for n in found.names if n not in joints]
    if missing:
        raise ConfigurationError(f"no measured joints for {', '.join(missing)}")
    views = [
        JointView(
            joints[n],
            v.points_B,
            v.pixels,
            None if holding_torque is None else holding_torque(joints[n]),
        )
        for n, v in zip(found.names, found.views, strict=True)
    ]
    X_WB = found.X_WF[0] @ seed.X_FC @ found.X_CB[0]
    return CalibrateJoints(X_WF, views, intrinsics, seed.X_FC, X_WB)


def WriteJointOffsets(out_dir: Path, calibration: KinematicCalibration, arm: str) -> Path:
    """Writes out_dir/joint_offsets.yaml (JointOffsetsFile) with the standard deviations as
    comments; returns its path."""
    n = calibration.joint_offset.size
    fitted = IdentifiableJoints(n)
    lines = [
        f"# Joint offsets of arm {arm} (`guidedarm calibrate hand-eye`): the true joint angle",
        "# minus the measured one (rad), for the arm's calibration_file. Joints "
        + ", ".join(str(i + 1) for i in range(n) if i not in fitted)
        + " are 0: their",
        "# offsets are not identifiable (the board pose and the camera mount absorb them).",
        "# Standard deviations (rad): "
        + ", ".join(f"{s:.2g}" for s in calibration.joint_offset_std),
        "joint_offset: [" + ", ".join(f"{v:.7f}" for v in calibration.joint_offset) + "]",
    ]
    path = out_dir / "joint_offsets.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def WriteHandEyeCamera(out_dir: Path, calibration: KinematicCalibration, source: str) -> Path:
    """Writes out_dir/hand_eye_camera.yaml: the camera model `source` names with the focal
    lengths the kinematic calibration fitted (the mount in hand_eye.yaml is right with these
    focal lengths); returns its path."""
    scale, std = calibration.focal_scale, calibration.focal_scale_std
    comments = [
        "The camera model of the hand-eye calibration (`guidedarm calibrate hand-eye`): the",
        f"intrinsics of {source} with fx and fy scaled by {1 + scale:.6f} (+- {std:.6f}),",
        "fitted with the arm's joints and the camera's mount: use it with hand_eye.yaml and",
        "joint_offsets.yaml.",
    ]
    path = out_dir / "hand_eye_camera.yaml"
    path.write_text(CameraFileText(calibration.intrinsics, comments))
    return path
