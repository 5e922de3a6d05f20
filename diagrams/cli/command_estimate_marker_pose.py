"""`guidedarm estimate-marker-pose IMAGE --camera CAMERA.yaml --panel PANEL.yaml`.

Prints the pose of the panel in the camera frame as JSON: `X_CP` (4 x 4 homogeneous
matrix, metres), `ids` (known markers used), `reprojection_error_px` (RMS), `std_mm` and
`std_deg` (the pose's standard deviations along and about the camera's x y z axes),
`model_check` (the k1 the corners ask for beside the camera file's; null with one marker),
`valid` and `why_invalid`.
Exit codes: 0 valid pose, 1 markers found but the pose is not trustworthy, 2 bad input
(unreadable image, size not matching the camera file, no marker, bad YAML).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import cv2

from guidedarm.diagrams.panel.panel_files import LoadCameraIntrinsics, LoadPanelSpec
from guidedarm.systems.errors import GuidedArmError
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver

INVALID_POSE = 1


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "estimate-marker-pose", help="pose of a marker panel in one camera image (JSON)"
    )
    parser.add_argument("image", type=Path, help="colour image (PNG, JPEG, ...)")
    parser.add_argument("--camera", type=Path, required=True, help="CAMERA.yaml intrinsics")
    parser.add_argument("--panel", type=Path, required=True, help="PANEL.yaml markers")
    parser.set_defaults(func=estimate_command)


def estimate_command(args: argparse.Namespace) -> int:
    intrinsics = LoadCameraIntrinsics(args.camera)
    panel = LoadPanelSpec(args.panel)
    solver = MarkerPoseSolver(intrinsics, panel)
    bgr = cv2.imread(str(args.image), cv2.IMREAD_COLOR) if args.image.is_file() else None
    if bgr is None:
        raise GuidedArmError(f"cannot read image {args.image} (missing or not an image file)")
    height, width = bgr.shape[:2]
    if (width, height) != (intrinsics.width, intrinsics.height):
        raise GuidedArmError(
            f"image {args.image} is {width} x {height} px, the camera file {args.camera} "
            f"says {intrinsics.width} x {intrinsics.height}"
        )
    estimate = solver.estimate(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    if not estimate.ids:
        known = [m.id for m in panel.markers]
        raise GuidedArmError(
            f"no marker of the panel ({panel.dictionary} ids {known}) found in {args.image}"
        )
    X_CP = estimate.X_CP.GetAsMatrix4().tolist() if estimate.X_CP is not None else None
    check = estimate.model_check
    result = {
        "X_CP": X_CP,
        "ids": estimate.ids,
        "reprojection_error_px": round(estimate.reprojection_error_px, 4),
        "std_mm": _Rounded(estimate.std_mm),
        "std_deg": _Rounded(estimate.std_deg),
        "model_check": None
        if check is None
        else {
            "fitted_k1": round(check.fitted_k1, 4),
            "fitted_k1_std": round(check.fitted_k1_std, 4),
            "file_k1": check.file_k1,
            "explained_px": round(check.explained_px, 3),
            "fits": check.fits,
        },
        "valid": estimate.valid,
        "why_invalid": estimate.why_invalid,
    }
    print(json.dumps(result))
    return 0 if estimate.valid else INVALID_POSE


def _Rounded(values: list[float]) -> list[float | None]:
    """Rounded to 4 decimals; an infinite deviation (an undetermined pose) as null."""
    return [round(v, 4) if math.isfinite(v) else None for v in values]
