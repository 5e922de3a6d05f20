"""`guidedarm calibrate camera | hand-eye SCENARIO --hardware`: the photo procedure on a cell
(CellPhotos: the arm moved to each view by its station's position_commanded, a photo and
the measured pose once it rests). No camera emulator exists (a camera double renders no
board), so the calibration from the photos is tested on the simulated station (the same
code with the station swapped, hardware=False); on hardware, the motion and capture
sequence against `emulate nachi` with a video-file camera, and the refusals."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
from hardware_doubles import (
    Mz04dCalibrationCell,
    StartNachiEmulator,
    StopServer,
    WriteTestVideo,
)
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import AddModel, AddWeld, ModelDirective

from guidedarm.diagrams.calibration.board_assets import DEFAULT_BOARD_FILE
from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.calibration.cell_photos import CellPhotos, HandEyeOnCell
from guidedarm.diagrams.calibration.hand_eye_calibration import ReadPoses
from guidedarm.diagrams.calibration.simulated_calibration import TakePhotos
from guidedarm.diagrams.tasks.registry import LoadScenario

BOARD = "package://guidedarm/calibration/charuco_board.sdf"


def _PanelWithBoard(overrides=()):
    """panel_operation with the board 40 mm in front of the panel plate, upright."""
    _, scenario, _ = LoadScenario("panel_operation", list(overrides))
    width, height = LoadBoardSpec(DEFAULT_BOARD_FILE).size_m()
    X_plate_B = RigidTransform(
        RollPitchYaw(np.pi, 0, 0), [0.06 - width / 2, height / 2 - 0.0125, 0.04]
    )
    board = [
        ModelDirective(add_model=AddModel(file=BOARD, name="calibration_board")),
        ModelDirective(
            add_weld=AddWeld(
                parent="panel::plate", child="calibration_board::board", X_PC=Transform(X_plate_B)
            )
        ),
    ]
    station = dataclasses.replace(
        scenario.station, directives=[*scenario.station.directives, *board]
    )
    return dataclasses.replace(scenario, station=station)


@pytest.mark.slow
def test_photos_taken_at_rest_at_each_view_give_the_mount(tmp_path):
    cell = CellPhotos(_PanelWithBoard(), hardware=False, speed_scale=1.0)
    planned = cell.PlanViews(6, seed=1)
    result = HandEyeOnCell(cell, tmp_path, TakePhotos(cell, tmp_path, 6, seed=1))
    # Each photo's recorded mount pose is the planned view's: taken at rest, there.
    poses = ReadPoses(tmp_path / "poses.csv")
    assert sorted(poses) == [f"view{k:02d}.png" for k in range(6)]
    for k, q in enumerate(planned):
        X_WF = cell.kinematics.X_WC(q) @ cell.X_FC_nominal.inverse()
        recorded = poses[f"view{k:02d}.png"]
        assert np.linalg.norm(recorded.translation() - X_WF.translation()) < 2e-4
    # The mount the photos give is the nominal one (no errors drawn): the images are those
    # of the recorded poses.
    error = cell.X_FC_nominal.inverse() @ result.X_FC
    angle = np.degrees(error.rotation().ToAngleAxis().angle())
    print(f"\nmount residual {np.linalg.norm(error.translation()) * 1e3:.3f} mm {angle:.4f} deg")
    assert np.linalg.norm(error.translation()) < 0.5e-3 and angle < 0.2


@pytest.mark.parametrize(
    "kind, settings, message",
    [
        ("camera", [], "calibrate --hardware: no arm driver for 'rover_arm'"),
        ("hand-eye", [], "calibrate --hardware: no arm driver for 'rover_arm'"),
        (
            "camera",
            ["--set", "station.errors_preset=c920"],
            "calibrate --hardware measures the real one: remove them",
        ),
        ("hand-eye", ["--images", "photos"], "--images: not with a SCENARIO"),
        ("camera", ["--speed-scale", "1.5"], "--speed-scale 1.5: must be in (0, 1]"),
    ],
)
def test_hardware_photos_refused_before_motion(run_cli, tmp_path, kind, settings, message):
    out = tmp_path / "out"
    code, stdout, err = run_cli(
        "calibrate", kind, "panel_operation", "--hardware", "--out", out, *settings
    )
    assert code == 2 and stdout == "", err
    assert len(err.strip().splitlines()) == 1 and message in err, err
    assert not out.exists()


def test_hardware_without_scenario_refused(run_cli, tmp_path):
    code, _, err = run_cli("calibrate", "camera", "--hardware", "--out", tmp_path / "c.yaml")
    assert code == 2 and "--hardware needs a SCENARIO" in err, err


# The MZ04D cell with a 640 x 480 camera on the flange looking along it, and the board face
# up on the table in front of the arm (a joint_tour scenario: its station may have drivers).
CAMERA_CELL = Mz04dCalibrationCell(
    f"""  - add_model: {{name: calibration_board, file: {BOARD}}}
  - add_weld:
      parent: world
      child: calibration_board::board
      X_PC: {{translation: [0.35, 0.0, 0.001], rotation: !Rpy {{deg: [180, 0, 0]}}}}
""",
    cameras="""    camera:
      name: camera
      width: 640
      height: 480
      focal: !FocalLength {x: 600.0, y: 600.0}
      X_PB: {base_frame: mz04d::flange}
""",
    camera_drivers='      camera: {source: "0"}\n',
)
WATCHDOG = 5.0  # s; the links' (not what this test is about)
VIEWS = 5


@pytest.mark.slow
def test_views_visited_and_photographed_on_the_emulated_arm(tmp_path):
    """Against `emulate nachi --lockstep` with the project's camera double, a video file of
    plain colours played by cv2.VideoCapture (no board in it): the arm visits every planned
    view and a photo of the camera's size is taken at each, with the emulated arm's measured
    pose; the photos then do not calibrate (no board), which fails the run after the motion
    with its cause (exit 1, summary.json), not as a refusal."""
    cell_file = tmp_path / "cell.yaml"
    cell_file.write_text(CAMERA_CELL)
    video = tmp_path / "colours.avi"
    WriteTestVideo(video, 640, 480, 1.0, 600)  # 600 s at 1 frame a second: outlasts the run
    emulator, port, device = StartNachiEmulator("--scenario", str(cell_file), "--lockstep")
    out = tmp_path / "out"
    drivers = [
        f"station.hardware.arms.mz04d=!NachiDriver {{port: {port}, lockstep: true, "
        f"watchdog: {WATCHDOG}, acceleration_limits: [10, 10, 10, 10, 10, 10]}}",
        f"station.hardware.cameras.camera={{source: {video}, watchdog: {WATCHDOG}}}",
        f"station.hardware.tof_tools.tof={{device: {device}, watchdog: {WATCHDOG}, "
        "lockstep: true}",
    ]
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "calibrate", "camera"]
    command += [str(cell_file), "--hardware", "--out", str(out), "--views", str(VIEWS)]
    command += ["--speed-scale", "1"] + [a for d in drivers for a in ("--set", d)]
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=600)
    finally:
        StopServer(emulator)
    assert run.returncode == 1, run.stderr
    assert f"{VIEWS} views of the board" in run.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"] is False and summary["failure"], summary
    assert "calibrate camera failed" in run.stderr
    images = sorted((out / "images").iterdir())
    assert [p.name for p in images] == [f"view{k:02d}.png" for k in range(VIEWS)]
    assert all(cv2.imread(str(p)).shape == (480, 640, 3) for p in images)
    _, scenario, _ = LoadScenario(str(cell_file), [])
    cell = CellPhotos(scenario, hardware=False, speed_scale=1.0)
    poses = ReadPoses(out / "poses.csv")
    for k, q in enumerate(cell.PlanViews(VIEWS, seed=0)):
        X_WF = cell.kinematics.X_WC(q) @ cell.X_FC_nominal.inverse()
        recorded = poses[f"view{k:02d}.png"]
        assert np.linalg.norm(recorded.translation() - X_WF.translation()) < 1e-3
