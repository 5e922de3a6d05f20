"""Panel operation on an imperfect cell with and without its calibration files.

For each draw of the c920 and rover_arm presets' errors (the camera's focal length,
principal point, residual distortion and mount; the arm's joint offsets and joint
compliance; random_seed 0..N-1): the simulated rover arm photographs the cell's board
(VIEWS views, 1x rendering), `calibrate camera` and `calibrate hand-eye` (with the arm's
joint offsets and the focal length) run on those photos, poses and joints, then
panel_operation runs twice from the same start: with the nominal files, and with
estimator_camera_file (the hand-eye's camera file), camera_mount_file and the arm's
calibration_file set to the calibrated ones. Prints the true press error
(|true_press_error_mm|, the tip against its target in the panel frame) per draw, the mean
and max of each, how many runs pressed their switch, and the calibration's own residuals
(the written mount against the true one in the measured flange, the joint offsets, the
focal length fx of the camera calibration and of the hand-eye against the true one).
With --calibration-only the panel runs are left out.

    .venv/bin/python tests/benchmarks/bench_calibration_panel.py [N] [OUT] [--calibration-only]
    (N = 5)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from guidedarm.diagrams.calibration.calibration_files import LoadHandEye, LoadJointOffsets
from guidedarm.diagrams.calibration.camera_calibration import CalibrateCameraFromImages
from guidedarm.diagrams.calibration.simulated_calibration import HandEyeFromFolder, TakePhotos
from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell
from guidedarm.diagrams.panel.panel_files import LoadCameraIntrinsics
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.calibration.joint_bundle_adjustment import IdentifiableJoints

GUIDEDARM = Path(sys.executable).with_name("guidedarm")
PRESETS = "station.errors_preset=c920,rover_arm"
VIEWS = 15


def CalibrationCell(seed: int) -> SimulatedCalibrationCell:
    """The simulated cell of draw `seed` (1x rendering)."""
    _, scenario, _ = LoadScenario(
        "panel_operation", [PRESETS, f"random_seed={seed}", "supersampling=1"]
    )
    return SimulatedCalibrationCell(scenario)


def Calibrate(cell: SimulatedCalibrationCell, seed: int, out: Path) -> list[str]:
    """The settings that give panel_operation the calibrated files of draw `seed`."""
    folder = TakePhotos(cell, out, VIEWS, seed)
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    calibration = CalibrateCameraFromImages(images, cell.spec, out / "camera.yaml", str(folder))
    HandEyeFromFolder(cell, out, folder, calibration.intrinsics, "camera.yaml")
    return [
        f"estimator_camera_file={(out / 'hand_eye_camera.yaml').resolve()}",
        f"camera_mount_file={(out / 'hand_eye.yaml').resolve()}",
        f"station.arms.{cell.scenario.arm}.calibration_file="
        f"{(out / 'joint_offsets.yaml').resolve()}",
    ]


def CalibrationResiduals(cell: SimulatedCalibrationCell, out: Path) -> tuple[float, ...]:
    """The written mount's residual against the true one in the measured flange (mm, deg),
    the largest residual of the identified joint offsets (mrad), and the residual of fx in
    the camera calibration's file and in the hand-eye's (px)."""
    error = cell.TrueMountInMeasuredFlange().inverse() @ (
        LoadHandEye(out / "hand_eye.yaml").X_PC.GetDeterministicValue()
    )
    fitted = IdentifiableJoints(cell.true_joint_offset.size)
    offsets = LoadJointOffsets(out / "joint_offsets.yaml")
    true_fx = cell.true_intrinsics.fx
    return (
        float(np.linalg.norm(error.translation()) * 1e3),
        float(np.degrees(error.rotation().ToAngleAxis().angle())),
        float(np.max(np.abs(offsets - cell.true_joint_offset)[fitted]) * 1e3),
        LoadCameraIntrinsics(out / "camera.yaml").fx - true_fx,
        LoadCameraIntrinsics(out / "hand_eye_camera.yaml").fx - true_fx,
    )


def ResidualText(residual: tuple[float, ...]) -> str:
    return (
        "mount residual {:.3f} mm {:.4f} deg, joint offsets within {:.3f} mrad, fx residual "
        "{:+.2f} px (camera calibration) {:+.2f} px (hand-eye)".format(*residual)
    )


def RunPanel(out: Path, settings: list[str]) -> tuple[float | None, bool]:
    """Runs panel_operation into `out`; returns ReadPress(out)."""
    flags = [a for s in settings for a in ("--set", s)]
    subprocess.run(
        [str(GUIDEDARM), "run", "panel_operation", "--out", str(out), *flags],
        check=False,
        capture_output=True,
    )
    return ReadPress(out)


def ReadPress(out: Path) -> tuple[float | None, bool]:
    """The true press error |true_press_error_mm| (mm; None: nothing pressed) of the run in
    `out`, and whether it pressed its switch (and no other)."""
    summary = json.loads((out / "summary.json").read_text())
    error = summary.get("true_press_error_mm")
    norm = float(np.linalg.norm([error["x"], error["y"], error["z"]])) if error else None
    return norm, bool(summary.get("success"))


def PrintTotals(rows: list[tuple]) -> None:
    """rows: (seed, nominal (error, success) or None, calibrated (error, success) or None,
    *CalibrationResiduals)."""
    for label, column in (("nominal files", 1), ("calibrated files", 2)):
        values = [r[column][0] for r in rows if r[column] and r[column][0] is not None]
        if not values:
            continue
        pressed = sum(r[column][1] for r in rows)
        print(
            f"{label}: true press error mean {np.mean(values):.2f} mm, max {np.max(values):.2f} "
            f"mm over {len(values)} presses; {pressed} of {len(rows)} pressed their switch"
        )
    residuals = np.array([r[3:] for r in rows])
    fx = np.abs(residuals[:, 3:])
    print(
        "calibration: mount residual mean {:.3f} mm {:.4f} deg, max {:.3f} mm {:.4f} deg; "
        "joint offsets within {:.3f} mrad; |fx residual| mean {:.2f} px, max {:.2f} px "
        "(camera calibration), mean {:.2f} px, max {:.2f} px (hand-eye)".format(
            *residuals[:, :2].mean(axis=0),
            *residuals[:, :2].max(axis=0),
            residuals[:, 2].max(),
            fx[:, 0].mean(),
            fx[:, 0].max(),
            fx[:, 1].mean(),
            fx[:, 1].max(),
        )
    )


def main() -> None:
    arguments = [a for a in sys.argv[1:] if a != "--calibration-only"]
    panel = len(arguments) == len(sys.argv) - 1
    count = int(arguments[0]) if arguments else 5
    root = Path(arguments[1]) if len(arguments) > 1 else Path("runs/bench_calibration_panel")
    rows = []
    for seed in range(count):
        cell = CalibrationCell(seed)
        out = root / f"draw{seed}" / "calibration"
        files = Calibrate(cell, seed, out)
        residual = CalibrationResiduals(cell, out)
        nominal = calibrated = None
        line = f"draw {seed}: "
        if panel:
            base = [PRESETS, f"random_seed={seed}"]
            nominal = RunPanel(root / f"draw{seed}" / "nominal", base)
            calibrated = RunPanel(root / f"draw{seed}" / "calibrated", [*base, *files])
            line += (
                f"true press error (mm, pressed its switch) {nominal} nominal, "
                f"{calibrated} calibrated; "
            )
        rows.append((seed, nominal, calibrated, *residual))
        print(line + ResidualText(residual), flush=True)
    PrintTotals(rows)


if __name__ == "__main__":
    main()
