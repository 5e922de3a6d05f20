"""`guidedarm calibrate camera | hand-eye | tof`: estimate the cell's nominal models from
data (photos, arm poses, ToF readings) and write the files the scenarios read.

  calibrate camera --images DIR --board BOARD.yaml --out CAMERA.yaml
      intrinsics and distortion of any camera from photos of a ChArUco board;
  calibrate camera SCENARIO --out DIR
      the same in simulation: the arm takes the photos of the cell's board (DIR/images/),
      DIR/camera.yaml is printed beside the simulated camera's truth;
  calibrate hand-eye --images DIR --poses POSES.csv --board BOARD.yaml --camera CAMERA.yaml
      --out OUT
      the camera's pose on the arm (OUT/hand_eye.yaml: X_PC) from recorded photos and poses;
  calibrate hand-eye SCENARIO --out DIR
      the same in simulation, printed beside the true mount;
  calibrate camera | hand-eye SCENARIO --hardware --out DIR [--speed-scale S]
      on the real cell: the arm moves its camera through the views of the printed board
      the scenario places (diagrams/calibration/cell_photos.py; DIR/summary.json, exit 1
      on a fault);
  calibrate tof SCENARIO --out DIR [--hardware] [--speed-scale S]
      each ToF sensor's offset against a flat target (DIR/tof_offsets.yaml): in simulation
      printed beside the drawn truth; where the scenario places the target in the cell
      (a `tof_target` model), the arm holds the tool over it, on the simulated station or
      with --hardware on the real one (DIR/summary.json; exit 1 on a fault).
SCENARIO is a panel_operation scenario for camera and hand-eye in simulation (with
--hardware one whose station may have drivers: a joint_tour of the cell with its camera),
one with a ToF tool (e.g. path_following) for tof, by name or file, with `--set key=value`
overrides.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.calibration.camera_calibration import (
    CalibrateCameraFromImages,
    ReadImageFolder,
)
from guidedarm.diagrams.calibration.hand_eye_calibration import (
    HandEyeFromImages,
    ReadPoses,
    WriteHandEye,
)
from guidedarm.diagrams.panel.panel_files import LoadCameraIntrinsics
from guidedarm.diagrams.run_context import PrepareOutputDirectory
from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.systems.calibration.camera_calibration_math import CameraCalibration
from guidedarm.systems.errors import ConfigurationError, GuidedArmError, RunFailedError

DEFAULT_VIEWS = 15
DEFAULT_SPEED_SCALE = 0.1  # as `guidedarm move-to-start`


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "calibrate", help="calibrate the cell: camera intrinsics, hand-eye, ToF offsets"
    )
    kinds = parser.add_subparsers(dest="kind", required=True)
    camera = kinds.add_parser("camera", help="camera intrinsics and distortion (ChArUco)")
    _AddSimulationArguments(camera)
    camera.add_argument("--images", type=Path, help="folder of board photos")
    camera.add_argument("--board", type=Path, help="BOARD.yaml")
    camera.add_argument("--out", type=Path, required=True, help="CAMERA.yaml (or DIR) to write")
    _AddHardwareArguments(camera, "the arm takes the photos on the real cell")
    camera.set_defaults(func=calibrate_camera_command)
    hand_eye = kinds.add_parser("hand-eye", help="the camera's pose on the arm")
    _AddSimulationArguments(hand_eye)
    hand_eye.add_argument("--images", type=Path, help="folder of board photos")
    hand_eye.add_argument("--poses", type=Path, help="POSES.csv: the mount's pose per photo")
    hand_eye.add_argument("--board", type=Path, help="BOARD.yaml")
    hand_eye.add_argument("--camera", type=Path, help="CAMERA.yaml of the camera")
    hand_eye.add_argument("--out", type=Path, required=True, help="output directory")
    _AddHardwareArguments(hand_eye, "the arm takes the photos on the real cell")
    hand_eye.set_defaults(func=calibrate_hand_eye_command)
    tof = kinds.add_parser("tof", help="ToF sensors' offsets against a flat target")
    tof.add_argument("scenario", help="scenario with one ToF tool (name or file)")
    tof.add_argument("--out", type=Path, required=True, help="output directory")
    _AddHardwareArguments(tof, "on the real cell: the arm holds the real tool")
    AddOverridesArgument(tof, "override a scenario key")
    tof.set_defaults(func=calibrate_tof_command)


def _AddHardwareArguments(parser: argparse.ArgumentParser, help: str) -> None:
    """--hardware and --speed-scale (the arm's moves on a cell)."""
    parser.add_argument("--hardware", action="store_true", help=help)
    parser.add_argument(
        "--speed-scale",
        type=float,
        default=DEFAULT_SPEED_SCALE,
        help="moves on a cell: fraction of the joints' velocity and acceleration limits "
        f"(default {DEFAULT_SPEED_SCALE})",
    )


def _CheckSpeedScale(args: argparse.Namespace) -> None:
    if not 0 < args.speed_scale <= 1:
        raise ConfigurationError(f"--speed-scale {args.speed_scale}: must be in (0, 1]")


def _AddSimulationArguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", nargs="?", help="panel_operation scenario (simulation)")
    parser.add_argument(
        "--views", type=int, default=DEFAULT_VIEWS, help=f"views in simulation ({DEFAULT_VIEWS})"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the views in simulation")
    AddOverridesArgument(parser, "override a scenario key")


def _CheckMode(args: argparse.Namespace, offline: tuple[str, ...]) -> bool:
    """True for simulation (a scenario), False for recorded data; refuses a mix."""
    given = [f"--{k}" for k in offline if getattr(args, k) is not None]
    if args.scenario is not None:
        if given:
            raise ConfigurationError(f"{', '.join(given)}: not with a SCENARIO (simulation)")
        if not 5 <= args.views <= 100:
            raise ConfigurationError(f"--views {args.views}: must be in [5, 100]")
        return True
    missing = [f"--{k}" for k in offline if getattr(args, k) is None]
    if missing:
        raise ConfigurationError(
            f"give a SCENARIO (simulation) or {', '.join(missing)} (recorded data)"
        )
    if args.overrides:
        raise ConfigurationError("--set applies to a SCENARIO only")
    return False


def _SimulatedCell(args: argparse.Namespace):
    # Imported here: building a station imports all of Drake's multibody and rendering.
    from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell
    from guidedarm.diagrams.tasks.registry import LoadScenario

    _, scenario, _ = LoadScenario(args.scenario, args.overrides)
    PrepareOutputDirectory(args.out)
    return SimulatedCalibrationCell(scenario)


def calibrate_camera_command(args: argparse.Namespace) -> int:
    if args.hardware:
        return _PhotosOnCell(args, ("images", "board"))
    if _CheckMode(args, ("images", "board")):
        from guidedarm.diagrams.calibration.simulated_calibration import CameraInSimulation

        calibration, lines = CameraInSimulation(
            _SimulatedCell(args), args.out, args.views, args.seed
        )
        _PrintCamera(calibration, args.out / "camera.yaml")
        print("\n".join(lines))
        return 0
    spec = LoadBoardSpec(args.board)
    if args.out.suffix not in (".yaml", ".yml"):
        raise ConfigurationError(f"--out {args.out}: must be a .yaml file")
    PrepareOutputDirectory(args.out.parent if str(args.out.parent) else Path("."))
    calibration = CalibrateCameraFromImages(
        ReadImageFolder(args.images), spec, args.out, str(args.images)
    )
    _PrintCamera(calibration, args.out)
    c, s = calibration.intrinsics, calibration.std_devs
    for name in ("fx", "fy", "cx", "cy"):
        print(f"  {name} = {getattr(c, name):9.2f} +- {s[name]:.2f} px")
    for name, value in zip(("k1", "k2", "p1", "p2", "k3"), c.distortion, strict=True):
        print(f"  {name} = {value:9.5f} +- {s[name]:.5f}")
    return 0


def _PrintCamera(calibration: CameraCalibration, out: Path) -> None:
    print(
        f"wrote {out} from {len(calibration.view_rms_px)} images "
        f"({len(calibration.rejected)} rejected), RMS {calibration.rms_px:.3f} px"
    )
    for name, why in calibration.rejected.items():
        print(f"  rejected {name}: {why}")


def calibrate_hand_eye_command(args: argparse.Namespace) -> int:
    if args.hardware:
        return _PhotosOnCell(args, ("images", "poses", "board", "camera"))
    if _CheckMode(args, ("images", "poses", "board", "camera")):
        from guidedarm.diagrams.calibration.simulated_calibration import HandEyeInSimulation

        result, lines = HandEyeInSimulation(_SimulatedCell(args), args.out, args.views, args.seed)
        print(f"wrote {args.out / 'hand_eye.yaml'} from {result.views} views")
        print("\n".join(lines))
        return 0
    spec = LoadBoardSpec(args.board)
    intrinsics = LoadCameraIntrinsics(args.camera)
    poses = ReadPoses(args.poses)
    images = ReadImageFolder(args.images)
    images = [(n, i) for n, i in images if n != args.poses.name or i is not None]
    PrepareOutputDirectory(args.out)
    result, rejected = HandEyeFromImages(images, poses, spec, intrinsics)
    path = WriteHandEye(args.out, result, rejected)
    print(
        f"wrote {path} from {result.views} views ({len(rejected)} rejected), method {result.method}"
    )
    for name, (p, r) in result.scatter.items():
        print(f"  {name:10s} board pose scatter {p:8.3f} mm {r:8.4f} deg")
    for name, why in rejected.items():
        print(f"  rejected {name}: {why}")
    return 0


def calibrate_tof_command(args: argparse.Namespace) -> int:
    from guidedarm.diagrams.calibration.tof_calibration import CalibrateToFInSimulation
    from guidedarm.diagrams.calibration.tof_on_cell import HasTarget
    from guidedarm.diagrams.tasks.registry import LoadScenario

    _CheckSpeedScale(args)
    task, scenario, _ = LoadScenario(args.scenario, args.overrides)
    station = getattr(scenario, "station", None)
    if args.hardware or (station is not None and HasTarget(station)):
        return _CalibrateToFOnCell(args, task, scenario)
    PrepareOutputDirectory(args.out)
    lines = CalibrateToFInSimulation(scenario, args.out)
    print(f"wrote {args.out / 'tof_offsets.yaml'}")
    print("\n".join(lines))
    return 0


def _CalibrateToFOnCell(args: argparse.Namespace, task, scenario) -> int:
    """The arm holds the tool over the cell's target, simulated or (--hardware) real."""
    from guidedarm.diagrams.calibration.tof_on_cell import RunToFCalibrationOnCell

    PrepareOutputDirectory(args.out)
    success, lines = RunToFCalibrationOnCell(
        task, scenario, args.out, args.hardware, args.speed_scale, args.argv
    )
    if not success:
        print("\n".join(lines), file=sys.stderr)
        return 1
    print(f"wrote {args.out / 'tof_offsets.yaml'}")
    print("\n".join(lines))
    return 0


def _PhotosOnCell(args: argparse.Namespace, offline: tuple[str, ...]) -> int:
    """`calibrate camera | hand-eye SCENARIO --hardware`: the arm takes the photos on the
    real cell (DIR/images/, poses.csv), then the offline calibration runs on them;
    DIR/summary.json either way, exit 1 when the motion faulted or the photos do not
    calibrate."""
    from guidedarm.diagrams.calibration.cell_motion import WriteCellSummary
    from guidedarm.diagrams.calibration.cell_photos import CameraOnCell, CellPhotos, HandEyeOnCell
    from guidedarm.diagrams.calibration.simulated_calibration import TakePhotos
    from guidedarm.diagrams.tasks.registry import LoadScenario

    if args.scenario is None:
        raise ConfigurationError("--hardware needs a SCENARIO (the cell's arm and camera)")
    _CheckMode(args, offline)
    _CheckSpeedScale(args)
    _, scenario, _ = LoadScenario(args.scenario, args.overrides)
    cell = CellPhotos(scenario, hardware=True, speed_scale=args.speed_scale)
    PrepareOutputDirectory(args.out)
    summary = {"kind": args.kind, "hardware": True}
    try:
        folder = TakePhotos(cell, args.out, args.views, args.seed)
    except (RunFailedError, KeyboardInterrupt) as e:
        return _CellFailed(args, summary, e)
    try:  # after the motion: photos that do not calibrate fail the run, not its input
        if args.kind == "camera":
            calibration = CameraOnCell(cell, args.out, folder)
            _PrintCamera(calibration, args.out / "camera.yaml")
            summary["rms_px"] = calibration.rms_px
        else:
            result = HandEyeOnCell(cell, args.out, folder)
            print(f"wrote {args.out / 'hand_eye.yaml'} from {result.views} views")
            summary["views"] = result.views
    except GuidedArmError as e:
        return _CellFailed(args, summary, e)
    WriteCellSummary(args.out, {**summary, "success": True, "failure": ""}, args.argv)
    return 0


def _CellFailed(args: argparse.Namespace, summary: dict, error: BaseException) -> int:
    """Writes DIR/summary.json with `failure` (`interrupted` for Ctrl-C); exit 1."""
    from guidedarm.diagrams.calibration.cell_motion import WriteCellSummary
    from guidedarm.diagrams.task_run import InterruptedFailure

    failure = InterruptedFailure(error) if isinstance(error, KeyboardInterrupt) else str(error)
    WriteCellSummary(args.out, {**summary, "success": False, "failure": failure}, args.argv)
    print(f"calibrate {args.kind} failed: {failure}", file=sys.stderr)
    return 1
