"""`guidedarm calibrate hand-eye` and `calibrate camera SCENARIO`: the camera's mount and
intrinsics recovered, offline from photos projected through a known lens and mount, and in
simulation from the station's rendered views of the cell's board."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import yaml
from pydrake.math import RigidTransform, RollPitchYaw

from guidedarm.diagrams.calibration.board_assets import DEFAULT_BOARD_FILE
from guidedarm.diagrams.calibration.calibration_files import (
    LoadBoardSpec,
    LoadHandEye,
    LoadJointOffsets,
)
from guidedarm.diagrams.calibration.simulated_cell import SimulatedCalibrationCell, TrueIntrinsics
from guidedarm.diagrams.panel.panel_files import IntrinsicsFromCameraConfig, LoadCameraIntrinsics
from guidedarm.diagrams.run_preparation import WithErrorsDrawn
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.calibration.board_projection import BoardPhotos
from guidedarm.systems.calibration.calibration_views import CalibrationViews
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

LENS = CameraIntrinsics(
    fx=1365.0, fy=1362.0, cx=962.0, cy=541.0, distortion=[-0.2, 0.06, 0.0, 0.0, 0.0]
)
X_FC = RigidTransform(RollPitchYaw(np.radians([1.5, -2.0, 91.0])), [0.012, -0.034, 0.051])
X_WB = RigidTransform(RollPitchYaw(np.radians([-90.0, 0.0, -90.0])), [0.9, 0.1, 0.7])


def _LoadX_PC(path):
    return LoadHandEye(path).X_PC.GetDeterministicValue()


def _FromMatrix34(matrix34: list) -> RigidTransform:
    return RigidTransform(np.array(matrix34))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Photos of the board through LENS from 8 camera poses, the mount poses X_WF that put
    the camera there through X_FC, and the files the offline command reads."""
    root = tmp_path_factory.mktemp("hand_eye")
    spec = LoadBoardSpec(DEFAULT_BOARD_FILE)
    views = CalibrationViews(spec, LENS, 8, seed=3)
    (root / "images").mkdir()
    rows = ["image,x,y,z,roll_deg,pitch_deg,yaw_deg"]
    for i, (X_BC, photo) in enumerate(zip(views, BoardPhotos(spec, LENS, views), strict=True)):
        cv2.imwrite(str(root / "images" / f"p{i}.png"), photo)
        X_WF = X_WB @ X_BC @ X_FC.inverse()
        rpy = np.degrees(RollPitchYaw(X_WF.rotation()).vector())
        rows.append(f"p{i}.png," + ",".join(f"{v:.9g}" for v in [*X_WF.translation(), *rpy]))
    (root / "poses.csv").write_text("\n".join(rows) + "\n")
    camera = root / "camera.yaml"
    camera.write_text(yaml.safe_dump({k: v for k, v in LENS.__dict__.items()}))
    return root


def _Offline(run_cli, root, out, **replace):
    args = {
        "images": root / "images",
        "poses": root / "poses.csv",
        "board": DEFAULT_BOARD_FILE,
        "camera": root / "camera.yaml",
    }
    args.update(replace)
    flat = [a for k, v in args.items() for a in (f"--{k}", v)]
    return run_cli("calibrate", "hand-eye", *flat, "--out", out)


def test_offline_hand_eye_recovers_the_mount(run_cli, recorded, tmp_path):
    code, out, err = _Offline(run_cli, recorded, tmp_path)
    assert code == 0, err
    X_PC = _LoadX_PC(tmp_path / "hand_eye.yaml")
    error = X_FC.inverse() @ X_PC
    assert np.linalg.norm(error.translation()) < 0.5e-3
    assert np.degrees(error.rotation().ToAngleAxis().angle()) < 0.2
    report = json.loads((tmp_path / "hand_eye_report.json").read_text())
    assert report["views_used"] == 8 and set(report["scatter_mm_deg"]) == {
        "tsai",
        "park",
        "horaud",
        "andreff",
        "daniilidis",
    }
    chosen = report["scatter_mm_deg"][report["method"]]
    assert all(chosen[0] <= s[0] for s in report["scatter_mm_deg"].values())
    assert f"method {report['method']}" in out


@pytest.mark.parametrize(
    "case, message",
    [
        ("header", "the header must be image,x,y,z,roll_deg,pitch_deg,yaw_deg"),
        ("few_poses", "4 views with an arm pose, at least 5 needed"),
        ("one_axis", "turn about fewer than two different axes"),
        ("mixed", "--images, --poses, --board, --camera: not with a SCENARIO"),
        ("missing", "give a SCENARIO (simulation) or --camera (recorded data)"),
    ],
)
def test_bad_hand_eye_input_is_one_line(run_cli, recorded, tmp_path, case, message):
    poses = recorded / "poses.csv"
    lines = poses.read_text().splitlines()
    if case == "header":
        poses = tmp_path / "p.csv"
        poses.write_text("image,x,y,z\n")
    elif case == "few_poses":
        poses = tmp_path / "p.csv"
        poses.write_text("\n".join(lines[:5]) + "\n")
    elif case == "one_axis":
        poses = tmp_path / "p.csv"
        # every mount pose turned about z only: the views then disagree with the photos,
        # but the check refuses before that
        rows = [lines[0]] + [f"p{i}.png,0.5,0,0.5,0,0,{10 * i}" for i in range(8)]
        poses.write_text("\n".join(rows) + "\n")
    if case in ("mixed", "missing"):
        files = ["--images", recorded, "--poses", poses, "--board", DEFAULT_BOARD_FILE]
        if case == "mixed":
            files = ["panel_operation", *files, "--camera", recorded / "camera.yaml"]
        code, out, err = run_cli("calibrate", "hand-eye", *files, "--out", tmp_path)
    else:
        code, out, err = _Offline(run_cli, recorded, tmp_path / "out", poses=poses)
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and message in err, err


@pytest.mark.slow
def test_simulated_camera_and_hand_eye_calibration(run_cli, tmp_path):
    """The simulated rover arm photographs the cell's board (8 views at 1x rendering) with a
    camera whose true optics and mount differ from its file (the c920 preset's errors and a
    k1 = -0.2 lens): intrinsics within 0.5 % and 3 px of the truth, k1 within 0.02; from the
    same photos and recorded poses the mount within 0.5 mm and 0.2 deg of the true one."""
    settings = [
        "supersampling=1",
        "random_seed=3",
        "station.errors_preset=c920",
        "station.errors.cameras.camera.distortion=[-0.2, 0.06, 0, 0, 0]",
    ]
    out = tmp_path / "camera"
    flags = [a for s in settings for a in ("--set", s)]
    code, stdout, err = run_cli(
        "calibrate", "camera", "panel_operation", "--out", out, "--views", 8, *flags
    )
    assert code == 0, err
    assert "truth" in stdout and "residual" in stdout
    _, scenario, _ = LoadScenario("panel_operation", settings)
    scenario = WithErrorsDrawn(scenario)
    errors = scenario.station.errors.cameras["camera"]
    truth = TrueIntrinsics(IntrinsicsFromCameraConfig(scenario.station.cameras["camera"]), errors)
    fit = LoadCameraIntrinsics(out / "camera.yaml")
    assert abs(fit.fx / truth.fx - 1) < 0.005 and abs(fit.fy / truth.fy - 1) < 0.005
    assert abs(fit.cx - truth.cx) < 3 and abs(fit.cy - truth.cy) < 3
    assert abs(fit.distortion[0] - truth.distortion[0]) < 0.02
    he = tmp_path / "hand_eye"
    code, stdout, err = run_cli(
        "calibrate",
        "hand-eye",
        "--images",
        out / "images",
        "--poses",
        out / "poses.csv",
        "--board",
        DEFAULT_BOARD_FILE,
        "--camera",
        out / "camera.yaml",
        "--out",
        he,
    )
    assert code == 0, err
    # The camera frame's nominal pose on its mount is the identity (X_PB, X_BC).
    error = errors.X_mount_error.GetDeterministicValue().inverse() @ _LoadX_PC(he / "hand_eye.yaml")
    assert np.linalg.norm(error.translation()) < 0.5e-3
    assert np.degrees(error.rotation().ToAngleAxis().angle()) < 0.2


@pytest.mark.slow
def test_simulated_hand_eye_calibrates_the_arm_too(run_cli, tmp_path):
    """The rover arm with the rover_arm preset's joint offsets (5 mrad sd) and compliance
    takes 12 views (1x rendering) with its nominal camera: the identified offsets of joints
    2-5 within 0.2 mrad, the mount within 0.5 mm and 0.2 deg of the true one in the measured
    flange, where the hand-eye alone is off by more; joint_offsets.yaml is what the arm's
    calibration_file reads."""
    settings = ["supersampling=1", "random_seed=3", "station.errors_preset=rover_arm"]
    flags = [a for s in settings for a in ("--set", s)]
    code, stdout, err = run_cli(
        "calibrate", "hand-eye", "panel_operation", "--out", tmp_path, "--views", 12, *flags
    )
    assert code == 0, err
    assert "not identifiable" in stdout
    _, scenario, _ = LoadScenario("panel_operation", settings)
    cell = SimulatedCalibrationCell(scenario)
    offsets = LoadJointOffsets(tmp_path / "joint_offsets.yaml")
    assert offsets[0] == 0 and offsets[5] == 0
    assert np.all(np.abs(offsets - cell.true_joint_offset)[1:5] < 0.2e-3), offsets
    truth = cell.TrueMountInMeasuredFlange()
    error = truth.inverse() @ _LoadX_PC(tmp_path / "hand_eye.yaml")
    assert np.linalg.norm(error.translation()) < 0.5e-3
    assert np.degrees(error.rotation().ToAngleAxis().angle()) < 0.2
    report = json.loads((tmp_path / "hand_eye_report.json").read_text())
    alone = _FromMatrix34(report["X_PC_by_method"][report["method"]])
    assert np.linalg.norm((cell.true_X_FC.inverse() @ alone).translation()) > 0.5e-3
