"""`guidedarm calibrate camera --images DIR --board BOARD.yaml --out CAMERA.yaml`: the
intrinsics of any camera from its photos of a ChArUco board.

Every file of DIR is tried (sorted by name); a file that is not an image, an image of
another size than the first one, or one without a usable view of the board is rejected
with the reason. Beside CAMERA.yaml go CAMERA_report.json (per-image RMS reprojection
error, the parameters' standard deviations, image coverage, rejected images and why) and
CAMERA_coverage.png (the corners used, per image, over the image frame).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from guidedarm.diagrams.calibration.calibration_files import CameraFileText
from guidedarm.diagrams.plots import FinishFigure, plt
from guidedarm.systems.calibration.camera_calibration_math import (
    BoardView,
    CalibrateCamera,
    CameraCalibration,
    FindBoardView,
)
from guidedarm.systems.calibration.charuco_board import BoardSpec, CharucoCornerDetector
from guidedarm.systems.errors import ConfigurationError

# Coverage is the fraction of the cells of a COVERAGE_GRID x COVERAGE_GRID grid over the
# image that hold at least one corner used: distortion is only determined where corners were.
COVERAGE_GRID = 8


def ReadBoardViews(
    images: list[tuple[str, np.ndarray | None]], spec: BoardSpec
) -> tuple[list[BoardView], dict[str, str], tuple[int, int]]:
    """The usable views among named images (None: the file could not be read as an image),
    the rejected ones with why, and the image size (width, height) of the first image."""
    detector = CharucoCornerDetector(spec)
    views, rejected, size = [], {}, None
    for name, image in images:
        if image is None:
            rejected[name] = "not an image file"
            continue
        shape = (image.shape[1], image.shape[0])
        size = size or shape
        if shape != size:
            rejected[name] = f"{shape[0]} x {shape[1]} px, the first image is {size[0]} x {size[1]}"
            continue
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        view = FindBoardView(detector, name, gray)
        if isinstance(view, str):
            rejected[name] = view
        else:
            views.append(view)
    if size is None:
        raise ConfigurationError("no image file among the files given")
    return views, rejected, size


def ReadImageFolder(folder: Path) -> list[tuple[str, np.ndarray | None]]:
    """(file name, BGR image or None when not readable as one) of each file in `folder`."""
    if not folder.is_dir():
        raise ConfigurationError(f"--images {folder}: not a directory")
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    if not files:
        raise ConfigurationError(f"--images {folder}: the folder is empty")
    return [(p.name, cv2.imread(str(p), cv2.IMREAD_COLOR)) for p in files]


def CalibrateCameraFromImages(
    images: list[tuple[str, np.ndarray | None]], spec: BoardSpec, out: Path, source: str
) -> CameraCalibration:
    """Calibrates from named images, writes `out` (CAMERA.yaml) and its report beside it;
    raises ConfigurationError (one line) when no calibration can be made."""
    views, rejected, (width, height) = ReadBoardViews(images, spec)
    if not views:
        raise ConfigurationError(
            f"no usable view of the board in {source} ({len(rejected)} files; first: "
            f"{next(iter(rejected))}: {next(iter(rejected.values()))})"
        )
    calibration = CalibrateCamera(views, width, height, rejected)
    coverage = _Coverage(views, calibration, width, height)
    comments = [
        f"Calibrated by `guidedarm calibrate camera` from {len(calibration.view_rms_px)} "
        f"views in {source}: RMS reprojection error {calibration.rms_px:.3f} px.",
        "std devs: "
        + ", ".join(f"{k} {v:.3g}" for k, v in calibration.std_devs.items())
        + " (px; distortion unitless).",
    ]
    out.write_text(CameraFileText(calibration.intrinsics, comments))
    report = {
        "camera_file": out.name,
        "views_used": len(calibration.view_rms_px),
        "rms_reprojection_error_px": round(calibration.rms_px, 4),
        "reprojection_error_px": {k: round(v, 4) for k, v in calibration.view_rms_px.items()},
        "std_devs": {k: float(f"{v:.4g}") for k, v in calibration.std_devs.items()},
        "coverage": round(coverage, 3),
        "rejected": calibration.rejected,
    }
    _ReportPath(out, "_report.json").write_text(json.dumps(report, indent=1) + "\n")
    _PlotCoverage(views, calibration, width, height, coverage, _ReportPath(out, "_coverage.png"))
    return calibration


def _ReportPath(out: Path, suffix: str) -> Path:
    return out.with_name(out.stem + suffix)


def _Used(views: list[BoardView], calibration: CameraCalibration) -> list[BoardView]:
    return [v for v in views if v.name in calibration.view_rms_px]


def _Coverage(views, calibration, width: int, height: int) -> float:
    cells = set()
    for v in _Used(views, calibration):
        i = np.clip((v.pixels[:, 0] / width * COVERAGE_GRID).astype(int), 0, COVERAGE_GRID - 1)
        j = np.clip((v.pixels[:, 1] / height * COVERAGE_GRID).astype(int), 0, COVERAGE_GRID - 1)
        cells.update(zip(i.tolist(), j.tolist(), strict=True))
    return len(cells) / COVERAGE_GRID**2


def _PlotCoverage(views, calibration, width, height, coverage: float, path: Path) -> None:
    figure, axis = plt.subplots(figsize=(8, 8 * height / width + 0.8))
    for v in _Used(views, calibration):
        axis.plot(v.pixels[:, 0], v.pixels[:, 1], ".", ms=3, label=v.name)
    axis.plot([0, width, width, 0, 0], [0, 0, height, height, 0], "k-", lw=1)
    axis.set_xlim(0, width)
    axis.set_ylim(height, 0)
    axis.set_xlabel("u (px)")
    axis.set_ylabel("v (px)")
    axis.set_title("board corners used, one colour per image")
    FinishFigure(
        figure,
        headline=f"coverage {coverage:.0%} of {COVERAGE_GRID} x {COVERAGE_GRID} cells, "
        f"RMS {calibration.rms_px:.3f} px",
    )
    figure.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(figure)
