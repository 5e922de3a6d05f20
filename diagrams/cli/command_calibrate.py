"""`guidedarm calibrate camera | hand-eye | tof`: estimate the cell's nominal models from
data (photos, arm poses, ToF readings) and write the files the scenarios read.

  calibrate camera --images DIR --board BOARD.yaml --out CAMERA.yaml
      intrinsics and distortion of any camera from photos of a ChArUco board.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.calibration.camera_calibration import (
    CalibrateCameraFromImages,
    ReadImageFolder,
)
from guidedarm.diagrams.run_context import PrepareOutputDirectory
from guidedarm.systems.errors import ConfigurationError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "calibrate", help="calibrate the cell: camera intrinsics, hand-eye, ToF offsets"
    )
    kinds = parser.add_subparsers(dest="kind", required=True)
    camera = kinds.add_parser("camera", help="camera intrinsics and distortion (ChArUco)")
    camera.add_argument("--images", type=Path, required=True, help="folder of board photos")
    camera.add_argument("--board", type=Path, required=True, help="BOARD.yaml")
    camera.add_argument("--out", type=Path, required=True, help="CAMERA.yaml to write")
    camera.set_defaults(func=calibrate_camera_command)


def calibrate_camera_command(args: argparse.Namespace) -> int:
    spec = LoadBoardSpec(args.board)
    if args.out.suffix not in (".yaml", ".yml"):
        raise ConfigurationError(f"--out {args.out}: must be a .yaml file")
    PrepareOutputDirectory(args.out.parent if str(args.out.parent) else Path("."))
    calibration = CalibrateCameraFromImages(
        ReadImageFolder(args.images), spec, args.out, str(args.images)
    )
    c = calibration.intrinsics
    s = calibration.std_devs
    print(
        f"wrote {args.out} from {len(calibration.view_rms_px)} images "
        f"({len(calibration.rejected)} rejected), RMS {calibration.rms_px:.3f} px"
    )
    for name in ("fx", "fy", "cx", "cy"):
        print(f"  {name} = {getattr(c, name):9.2f} +- {s[name]:.2f} px")
    for name, value in zip(("k1", "k2", "p1", "p2", "k3"), c.distortion, strict=True):
        print(f"  {name} = {value:9.5f} +- {s[name]:.5f}")
    for name, why in calibration.rejected.items():
        print(f"  rejected {name}: {why}")
    return 0
