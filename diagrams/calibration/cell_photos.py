"""`guidedarm calibrate camera | hand-eye SCENARIO --out DIR --hardware`: the arm takes the
calibration photos of a printed ChArUco board on the real cell, and the offline
calibrations run on them as on the simulated cell's (simulated_calibration.py).

CellPhotos is the simulated cell's counterpart with the station swapped: the views are the
same generated ones (CalibrationViews, reached by IK on the controller's model), but the
arm moves to each on a rest-to-rest joint move streamed to its driver (cell_motion.py)
and each photo is the camera driver's newest frame after the arm has rested SETTLE_S
plus CAPTURE_FRAMES frame periods; the pose recorded with it, X_WF of the camera's mount
frame, comes from the measured joints and the nominal model, as a real cell records it.
The board is a model instance `calibration_board` of the scenario's directives, welded
where the printed board stands (its pose only aims the views: the calibrations do not
read it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

from guidedarm.diagrams.calibration.board_assets import DEFAULT_BOARD_FILE
from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.calibration.camera_calibration import CalibrateCameraFromImages
from guidedarm.diagrams.calibration.cell_motion import (
    ArmJointLimits,
    CheckMovesClear,
    MeasuredJoints,
    Schedule,
    StreamToArm,
)
from guidedarm.diagrams.calibration.hand_eye_calibration import (
    HandEyeFromImages,
    ReadPoses,
    WriteHandEye,
)
from guidedarm.diagrams.calibration.simulated_cell import SimulatedView
from guidedarm.diagrams.panel.panel_files import IntrinsicsFromCameraConfig
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.diagrams.tasks.panel_operation import MakeCameraArmKinematics
from guidedarm.systems.calibration.calibration_views import CalibrationViews
from guidedarm.systems.calibration.camera_calibration_math import CameraCalibration
from guidedarm.systems.calibration.hand_eye_math import HandEyeResult
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.plant_frames import GetScopedFrame

BOARD_MODEL = "calibration_board"
BOARD_FRAME = f"{BOARD_MODEL}::board"
SETTLE_S = 0.5  # s at rest before a photo: the arm settles
CAPTURE_FRAMES = 3  # frame periods more: the newest frame was exposed at rest
VIEW_DISTANCE_M = (0.28, 0.45)  # the camera's distance from the board's centre (m)
VIEW_MAX_TILT_DEG = 30.0
SIMULATED_ACCELERATION = 1.5  # rad/s^2, the panel planner's rover-arm default


class CellPhotos:
    """The cell of a scenario with an `arm` carrying a camera (panel_operation: its `camera`,
    `tip_frame` and estimator's camera model; joint_tour: the station's one camera) whose
    directives place the board; Photos(count, seed) takes the views on its station
    (`hardware`: the hardware station, its links proved before anything moves; else the
    simulated one) at `speed_scale` times the arm's joint limits."""

    def __init__(self, scenario: Any, hardware: bool, speed_scale: float) -> None:
        self.scenario = scenario
        self.hardware = hardware
        self.speed_scale = speed_scale
        self.arm, self.camera = CheckPhotoCell(scenario, hardware)
        station = scenario.station
        self.spec = LoadBoardSpec(DEFAULT_BOARD_FILE)
        config = station.cameras[self.camera]
        self.nominal_intrinsics = IntrinsicsFromCameraConfig(config)
        estimator = getattr(scenario, "EstimatorIntrinsics", lambda: None)()
        self.estimator_intrinsics = estimator or self.nominal_intrinsics
        self.mount_frame = config.X_PB.base_frame
        self.kinematics = MakeCameraArmKinematics(
            station, self.arm, self.camera, getattr(scenario, "tip_frame", self.mount_frame)
        )
        plant = MakeMultibodyPlant(station)
        board = GetScopedFrame(plant, BOARD_FRAME, "the calibration board")
        self.X_WB = board.CalcPoseInWorld(plant.CreateDefaultContext())
        self.X_FC_nominal = (
            config.X_PB.GetDeterministicValue() @ config.X_BC.GetDeterministicValue()
        )

    def PlanViews(self, count: int, seed: int) -> list[np.ndarray]:
        """The joints (rad) of `count` views of the board (views out of reach replaced by
        others, each solved from the one before); refused when too few are reachable."""
        candidates = CalibrationViews(
            self.spec,
            self.estimator_intrinsics,
            6 * count,
            seed,
            distance_m=VIEW_DISTANCE_M,
            max_tilt_deg=VIEW_MAX_TILT_DEG,
        )
        kin = self.kinematics
        q = kin.plant.GetPositions(kin.plant.CreateDefaultContext())
        poses = []
        for X_BC in candidates:
            solution = kin.SolveTip(self.X_WB @ X_BC @ kin.X_CT, q)
            if solution is not None:
                q = solution
                poses.append(q)
            if len(poses) == count:
                return poses
        raise ConfigurationError(
            f"the arm reaches only {len(poses)} of the {count} views of the board wanted"
        )

    def Photos(self, count: int, seed: int) -> list[SimulatedView]:
        """Moves the arm through the planned views (refusals before motion) and takes one
        photo at each (names view00, view01, ...)."""
        poses = self.PlanViews(count, seed)
        arm, camera = self.arm, self.camera
        station_scenario = self.scenario.station
        fps = station_scenario.cameras[camera].fps
        # In simulation an arm whose model has no acceleration limits (the rover arm's)
        # moves within SIMULATED_ACCELERATION; on hardware its driver entry gives them.
        fallback = None if self.hardware else SIMULATED_ACCELERATION
        limits = ArmJointLimits(station_scenario, arm, fallback)
        rest = SETTLE_S + CAPTURE_FRAMES / fps
        rests = [rest] * len(poses)
        # Checked before any link is connected from the first view on; the move from where
        # the arm is measured to the first view once it is.
        planned, _ = Schedule(poses[0], poses, rests, limits, self.speed_scale)
        CheckMovesClear(station_scenario, arm, planned, "calibrate")
        station = MakeStation(station_scenario, kind="hardware" if self.hardware else "simulation")
        q_start = MeasuredJoints(station, arm)
        first, _ = Schedule(q_start, poses[:1], [0.0], limits, 1.0)
        CheckMovesClear(station_scenario, arm, first, "calibrate")
        trajectory, windows = Schedule(q_start, poses, rests, limits, self.speed_scale)
        print(
            f"calibrate: {len(poses)} views of the board in {trajectory.end_time():.1f} s",
            flush=True,
        )
        image_port = station.GetOutputPort(f"{camera}.rgb_image")
        joints_port = station.GetOutputPort(f"{arm}.position_measured")
        step = 1.0 / fps
        views: list[SimulatedView] = []

        def Observe(t: float, context) -> None:
            k = len(views)
            if k < len(windows) and t >= windows[k][1] - step / 2:
                q = np.array(joints_port.Eval(context))
                image = np.array(image_port.Eval(context).data)
                X_WF = self.kinematics.X_WC(q) @ self.X_FC_nominal.inverse()
                views.append(SimulatedView(f"view{k:02d}", image, q, X_WF))

        StreamToArm(station, arm, trajectory, step, Observe, self.hardware)
        return views


def CheckPhotoCell(scenario: Any, hardware: bool) -> tuple[str, str]:
    """The arm and the camera of the cell; refuses before anything is built: a scenario
    without an arm or a camera, on hardware simulated errors or the arm or the camera
    without its driver entry, a station without the board."""
    station = getattr(scenario, "station", None)
    arm = getattr(scenario, "arm", "")
    cameras = list(getattr(station, "cameras", {}))
    camera = getattr(scenario, "camera", cameras[0] if len(cameras) == 1 else "")
    if not arm or not camera:
        raise ConfigurationError(
            "calibration on a cell needs a scenario with an arm carrying one camera "
            f"(panel_operation, joint_tour), got task '{getattr(scenario, 'task', '?')}' "
            f"with cameras {cameras}"
        )
    if hardware and station.HasErrors():
        raise ConfigurationError(
            "station.errors and station.errors_preset describe a simulated cell; "
            "calibrate --hardware measures the real one: remove them"
        )
    for section, name, kind in (("arms", arm, "arm"), ("cameras", camera, "camera")):
        if hardware and name not in getattr(station.hardware, section):
            raise ConfigurationError(
                f"calibrate --hardware: no {kind} driver for '{name}' "
                f"(station.hardware.{section}.{name}, docs/hardware.md)"
            )
    if not MakeMultibodyPlant(station).HasModelInstanceNamed(BOARD_MODEL):
        raise ConfigurationError(
            f"calibrate --hardware: the station has no '{BOARD_MODEL}' model; add the "
            "printed board's directive (package://guidedarm/calibration/charuco_board.sdf, "
            "welded where it stands; docs/calibration.md)"
        )
    return arm, camera


def CameraOnCell(cell: CellPhotos, out_dir: Path, folder: Path) -> CameraCalibration:
    """Calibrates the camera from the photos in `folder` into out_dir/camera.yaml."""
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    return CalibrateCameraFromImages(images, cell.spec, out_dir / "camera.yaml", str(folder))


def HandEyeOnCell(cell: CellPhotos, out_dir: Path, folder: Path) -> HandEyeResult:
    """Calibrates the camera's mount from the photos in `folder` and out_dir/poses.csv into
    out_dir/hand_eye.yaml, with the estimator's camera model."""
    images = [(p.name, cv2.imread(str(p))) for p in sorted(folder.iterdir())]
    poses = ReadPoses(out_dir / "poses.csv")
    result, rejected = HandEyeFromImages(images, poses, cell.spec, cell.estimator_intrinsics)
    WriteHandEye(out_dir, result, rejected, cell.mount_frame)
    return result
