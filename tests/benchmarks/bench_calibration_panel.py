"""Panel operation on an imperfect cell with and without its calibration files.

For each draw of the c920 preset's camera errors (focal length, principal point, residual
distortion, the camera's mount; random_seed 0..N-1): the simulated rover arm photographs
the cell's board (10 views, 1x rendering), `calibrate camera` and `calibrate hand-eye` run
on those photos and poses, then panel_operation runs twice from the same start: with the
nominal files, and with estimator_camera_file and camera_mount_file set to the calibrated
ones. Prints the true press error (|true_press_error_mm|, the tip against its target in
the panel frame) per draw and the mean and max of each.

    .venv/bin/python tests/benchmarks/bench_calibration_panel.py [N] [OUT]   (N = 5)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from guidedarm.diagrams.calibration.camera_calibration import CalibrateCameraFromImages
from guidedarm.diagrams.calibration.hand_eye_calibration import (
    HandEyeFromImages,
    ReadPoses,
    WriteHandEye,
)
from guidedarm.diagrams.calibration.simulated_calibration import TakePhotos
from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell
from guidedarm.diagrams.tasks.registry import LoadScenario

GUIDEDARM = Path(sys.executable).with_name("guidedarm")


def Calibrate(seed: int, out: Path) -> tuple[Path, Path]:
    """camera.yaml and hand_eye.yaml of draw `seed`."""
    _, scenario, _ = LoadScenario(
        "panel_operation", ["station.errors_preset=c920", f"random_seed={seed}", "supersampling=1"]
    )
    cell = SimulatedCalibrationCell(scenario)
    folder = TakePhotos(cell, out, 10, seed)
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    calibration = CalibrateCameraFromImages(images, cell.spec, out / "camera.yaml", str(folder))
    result, rejected = HandEyeFromImages(
        images, ReadPoses(out / "poses.csv"), cell.spec, calibration.intrinsics
    )
    WriteHandEye(out, result, rejected, cell.mount_frame)
    return out / "camera.yaml", out / "hand_eye.yaml"


def PressError(out: Path, settings: list[str]) -> float | None:
    flags = [a for s in settings for a in ("--set", s)]
    subprocess.run(
        [str(GUIDEDARM), "run", "panel_operation", "--out", str(out), *flags],
        check=False,
        capture_output=True,
    )
    summary = json.loads((out / "summary.json").read_text())
    error = summary.get("true_press_error_mm")
    if not summary.get("success") or not error:
        return None
    return float(np.linalg.norm([error["x"], error["y"], error["z"]]))


def main() -> None:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    root = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("runs/bench_calibration_panel")
    rows = []
    for seed in range(count):
        camera, mount = Calibrate(seed, root / f"draw{seed}" / "calibration")
        base = ["station.errors_preset=c920", f"random_seed={seed}"]
        nominal = PressError(root / f"draw{seed}" / "nominal", base)
        calibrated = PressError(
            root / f"draw{seed}" / "calibrated",
            [
                *base,
                f"estimator_camera_file={camera.resolve()}",
                f"camera_mount_file={mount.resolve()}",
            ],
        )
        rows.append((seed, nominal, calibrated))
        print(
            f"draw {seed}: true press error {nominal} mm nominal, {calibrated} mm calibrated",
            flush=True,
        )
    for label, column in (("nominal files", 1), ("calibrated files", 2)):
        values = [r[column] for r in rows if r[column] is not None]
        failed = sum(r[column] is None for r in rows)
        print(
            f"{label}: mean {np.mean(values):.2f} mm, max {np.max(values):.2f} mm over "
            f"{len(values)} presses ({failed} without a press)"
        )


if __name__ == "__main__":
    main()
