"""The files of the calibration commands: BOARD.yaml in, CAMERA.yaml (as the marker
estimator reads it, diagrams/panel/panel_files.py) and hand_eye.yaml out.

No `from __future__ import annotations` here: yaml_load_typed reads HandEyeFile's
annotations."""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.scenario_loading import ScenarioError, load_typed, read_raw_scenario
from guidedarm.diagrams.station.model_paths import MODELS_DIR
from guidedarm.systems.calibration.charuco_board import BoardSpec
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics


@dataclass
class HandEyeFile:
    """hand_eye.yaml: X_PC, the camera's optical frame C in the frame it is mounted on
    (its base_frame), a Drake schema Transform that replaces the camera's X_PB."""

    X_PC: Transform = field(default_factory=Transform)


def LoadHandEye(path: str | Path) -> HandEyeFile:
    """The X_PC of a hand_eye.yaml written by `guidedarm calibrate hand-eye`."""
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"file not found: {path}")
    return load_typed(HandEyeFile, read_raw_scenario(path), str(path))


@dataclass
class ToFOffsetsFile:
    """tof_offsets.yaml: how much each of the six sensors reads too long (m), the amount
    the ToF tool's calibration_file subtracts."""

    offset: list[float] = field(default_factory=lambda: [0.0] * 6)


def LoadToFOffsets(path: str | Path) -> np.ndarray:
    """The six offsets (m) of a tof_offsets.yaml (relative to models/ or absolute),
    refused unless six values within +-0.1 m (the sensor's range)."""
    path = MODELS_DIR / path
    if not path.is_file():
        raise ScenarioError(f"file not found: {path}")
    offsets = load_typed(ToFOffsetsFile, read_raw_scenario(path), str(path)).offset
    if len(offsets) != 6 or not all(abs(v) <= 0.1 for v in offsets):
        raise ScenarioError(f"{path}: offset must hold 6 values within +-0.1 m, got {offsets}")
    return np.asarray(offsets, float)


@dataclass
class JointOffsetsFile:
    """joint_offsets.yaml: per joint of an arm, the true joint angle minus the measured one
    (rad), as `guidedarm calibrate hand-eye` identifies it; the arm's calibration_file adds it
    to every measured position."""

    joint_offset: list[float] = field(default_factory=list)


def LoadJointOffsets(path: str | Path) -> np.ndarray:
    """The joint offsets (rad) of a joint_offsets.yaml (relative to models/ or absolute),
    refused unless every value is within +-0.2 rad (a zero set at assembly, not a pose)."""
    path = MODELS_DIR / path
    if not path.is_file():
        raise ScenarioError(f"file not found: {path}")
    offsets = load_typed(JointOffsetsFile, read_raw_scenario(path), str(path)).joint_offset
    if not offsets or not all(abs(v) <= 0.2 for v in offsets):
        raise ScenarioError(
            f"{path}: joint_offset must hold one value per joint within +-0.2 rad, got {offsets}"
        )
    return np.asarray(offsets, float)


def LoadBoardSpec(path: str | Path) -> BoardSpec:
    """The board in a BOARD.yaml file, checked (bounds, marker smaller than square, enough
    markers in the dictionary)."""
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"file not found: {path}")
    return load_typed(BoardSpec, read_raw_scenario(path), str(path))


def CameraFileText(intrinsics: CameraIntrinsics, comments: list[str]) -> str:
    """A CAMERA.yaml: `comments` as # lines, then the intrinsics (px) and distortion."""
    lines = [f"# {c}" for c in comments]
    lines += [f"width: {intrinsics.width}", f"height: {intrinsics.height}"]
    lines += [f"{k}: {getattr(intrinsics, k):.4f}" for k in ("fx", "fy", "cx", "cy")]
    lines.append("distortion: [" + ", ".join(f"{d:.6g}" for d in intrinsics.distortion) + "]")
    return "\n".join(lines) + "\n"


def TransformFileText(name: str, X: RigidTransform, comments: list[str]) -> str:
    """A YAML mapping holding one Drake schema Transform `name` (translation in m,
    rotation as !Rpy in deg), after `comments` as # lines."""
    rpy = np.degrees(RollPitchYaw(X.rotation()).vector())
    lines = [f"# {c}" for c in comments]
    lines += [
        f"{name}:",
        "  translation: [" + ", ".join(f"{v:.6f}" for v in X.translation()) + "]",
        "  rotation: !Rpy { deg: [" + ", ".join(f"{v:.5f}" for v in rpy) + "] }",
    ]
    return "\n".join(lines) + "\n"
