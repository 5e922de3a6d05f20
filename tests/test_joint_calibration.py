"""The arm's kinematic calibration (joint offsets with the camera's mount) and the arm's
calibration_file: the bundle adjustment recovers known joint offsets and the mount from
synthetic corner views of the rover arm (with the camera's focal length when the model given
is off), and the station's measured joints gain the file's
offsets."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.calibration.board_assets import DEFAULT_BOARD_FILE
from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec, LoadJointOffsets
from guidedarm.diagrams.calibration.hand_eye_joints import WriteJointOffsets
from guidedarm.diagrams.panel.panel_files import IntrinsicsFromCameraConfig
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.panel_operation import MakeCameraArmKinematics
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.calibration.calibration_views import CalibrationViews, ProjectPoints
from guidedarm.systems.calibration.charuco_board import CharucoCornerDetector
from guidedarm.systems.calibration.hand_eye_math import BoardPose, CalibrateHandEye
from guidedarm.systems.calibration.joint_bundle_adjustment import (
    CalibrateJoints,
    JointView,
    ScaledFocalLength,
)
from guidedarm.systems.errors import ConfigurationError

TRUE_OFFSET = np.array([0.004, -0.006, 0.005, 0.007, -0.004, 0.006])  # rad, ~the preset's sd
TRUE_X_FC = RigidTransform(RollPitchYaw(np.radians([0.8, -0.5, 1.0])), [0.001, -0.002, 0.0015])


def _RoverViews(true_focal_scale: float):
    """12 views of the board by the rover arm (IK on its model), corners projected from the
    true joints (measured + TRUE_OFFSET) and TRUE_X_FC through the nominal C920 with its
    focal lengths times 1 + true_focal_scale, with 0.1 px noise; the kinematics X_WF(q),
    the nominal intrinsics (the calibration's given model) and the start joints."""
    _, scenario, _ = LoadScenario("panel_operation", [])
    kin = MakeCameraArmKinematics(
        scenario.station, scenario.arm, scenario.camera, scenario.tip_frame
    )
    intrinsics = IntrinsicsFromCameraConfig(scenario.station.cameras[scenario.camera])
    true_intrinsics = ScaledFocalLength(intrinsics, true_focal_scale)
    spec = LoadBoardSpec(DEFAULT_BOARD_FILE)
    q0 = kin.plant.GetPositions(kin.plant.CreateDefaultContext())
    X_WB = kin.X_WC(q0) @ RigidTransform([-0.12, -0.09, 0.35])
    points_B = CharucoCornerDetector(spec).CornerPoints_B(
        np.arange((spec.squares_x - 1) * (spec.squares_y - 1))
    )
    rng = np.random.default_rng(1)
    views = []
    for X_BC in CalibrationViews(spec, intrinsics, 40, 0, (0.28, 0.45), 30.0):
        q = kin.SolveTip(X_WB @ X_BC @ kin.X_CT, q0)
        if q is None:
            continue
        X_CB = (kin.X_WC(q) @ TRUE_X_FC).inverse() @ X_WB
        pixels = ProjectPoints(true_intrinsics, X_CB, points_B)
        pixels = pixels + rng.normal(0, 0.1, pixels.shape)
        views.append(JointView(q - TRUE_OFFSET, points_B, pixels))
        if len(views) == 12:
            break
    return kin.X_WC, views, intrinsics, q0


@pytest.fixture(scope="module")
def rover_views():
    return _RoverViews(0.0)


def _Fit(X_WF, views, intrinsics):
    """CalibrateJoints seeded by OpenCV's hand-eye on the same views, and the seed."""
    X_CB = [BoardPose(v.points_B, v.pixels, intrinsics) for v in views]
    seed = CalibrateHandEye([X_WF(v.q) for v in views], X_CB)
    X_WB_seed = X_WF(views[0].q) @ seed.X_FC @ X_CB[0]
    return CalibrateJoints(X_WF, views, intrinsics, seed.X_FC, X_WB_seed), seed


def _TrueMountInMeasuredFlange(X_WF, q0) -> RigidTransform:
    last = np.zeros(6)
    last[5] = TRUE_OFFSET[5]
    return X_WF(q0).inverse() @ X_WF(q0 + last) @ TRUE_X_FC


def test_bundle_adjustment_recovers_offsets_and_mount(rover_views):
    """Joints 2-5 within 0.1 mrad; the mount within 0.1 mm and 0.02 deg of the true one in
    the frame of the measured last joint, where OpenCV's hand-eye alone (the seed) is
    off by more than 1 mm; joints 1 and 6 (gauge freedoms) stay 0."""
    X_WF, views, intrinsics, q0 = rover_views
    fit, seed = _Fit(X_WF, views, intrinsics)
    assert np.all(np.abs(fit.joint_offset[1:5] - TRUE_OFFSET[1:5]) < 1e-4), fit.joint_offset
    assert fit.joint_offset[0] == 0 and fit.joint_offset[5] == 0
    assert np.all(fit.joint_offset_std[1:5] < 1e-4) and fit.rms_px < 0.2
    truth = _TrueMountInMeasuredFlange(X_WF, q0)
    for X_FC, bound_mm in ((fit.X_FC, 0.1), (seed.X_FC, None)):
        error = truth.inverse() @ X_FC
        if bound_mm is None:
            assert np.linalg.norm(error.translation()) > 1e-3
        else:
            assert np.linalg.norm(error.translation()) < bound_mm * 1e-3
            assert np.degrees(error.rotation().ToAngleAxis().angle()) < 0.02


def test_bundle_adjustment_fits_the_focal_length_with_the_mount():
    """The camera's true focal lengths 0.5 % longer than the model given (6.8 px, the c920
    preset's spread of an uncalibrated file; with them fixed the mount would move by 0.5 %
    of the views' 280-450 mm along the optical axis): the fit finds the focal scale within 3
    of its standard deviations (below 0.03 %, 0.4 px) and the mount within 0.1 mm and
    0.02 deg, the offsets within 0.1 mrad; fx / fy stays the given model's."""
    X_WF, views, intrinsics, q0 = _RoverViews(0.005)
    fit, _ = _Fit(X_WF, views, intrinsics)
    assert fit.focal_scale_std < 3e-4 and abs(fit.focal_scale - 0.005) < 3 * fit.focal_scale_std
    assert abs(fit.intrinsics.fx - intrinsics.fx * (1 + fit.focal_scale)) < 1e-9
    assert abs(fit.intrinsics.fy / fit.intrinsics.fx - intrinsics.fy / intrinsics.fx) < 1e-12
    assert np.all(np.abs(fit.joint_offset[1:5] - TRUE_OFFSET[1:5]) < 1e-4), fit.joint_offset
    error = _TrueMountInMeasuredFlange(X_WF, q0).inverse() @ fit.X_FC
    assert np.linalg.norm(error.translation()) < 0.1e-3, error.translation()
    assert np.degrees(error.rotation().ToAngleAxis().angle()) < 0.02


def test_too_few_views_are_refused(rover_views):
    X_WF, views, intrinsics, _ = rover_views
    message = "6 views for a kinematic calibration of 4 joint parameters, at least 7"
    with pytest.raises(ConfigurationError, match=message):
        CalibrateJoints(X_WF, views[:6], intrinsics, RigidTransform(), RigidTransform())


def test_calibration_file_adds_the_offsets_to_the_measured_joints(tmp_path):
    """With station.errors' joint offsets and a calibration_file holding the same offsets,
    the simulated station's measured joints are the true ones (rigid, exact encoders); a
    file of the wrong length is refused naming the key."""
    fit = type("Fit", (), {"joint_offset": TRUE_OFFSET, "joint_offset_std": 0 * TRUE_OFFSET})
    path = WriteJointOffsets(tmp_path, fit, "rover_arm")
    np.testing.assert_allclose(LoadJointOffsets(path), TRUE_OFFSET, atol=1e-7)
    offsets = "[" + ", ".join(str(v) for v in TRUE_OFFSET) + "]"
    settings = [
        f"station.errors.arms.rover_arm.joint_offset={offsets}",
        f"station.arms.rover_arm.calibration_file={path}",
    ]
    _, scenario, _ = LoadScenario("panel_operation", settings)
    station = MakeStation(scenario.station)
    simulator = Simulator(station)
    context = station.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant = station.GetSubsystemByName("plant")
    q_true = plant.GetPositions(
        plant.GetMyContextFromRoot(simulator.get_context()),
        plant.GetModelInstanceByName("rover_arm"),
    )
    station.GetInputPort("rover_arm.position_commanded").FixValue(context, q_true)
    measured = station.GetOutputPort("rover_arm.position_measured").Eval(context)
    np.testing.assert_allclose(measured, q_true, atol=1e-12)
    (tmp_path / "short.yaml").write_text("joint_offset: [0.001, 0.002]\n")
    _, scenario, _ = LoadScenario(
        "panel_operation", [f"station.arms.rover_arm.calibration_file={tmp_path / 'short.yaml'}"]
    )
    with pytest.raises(ConfigurationError, match="calibration_file has 2 joint offsets"):
        MakeStation(scenario.station)


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "key 'station.arms.rover_arm.calibration_file': file not found"),
        ("joint_offset: [0.5, 0, 0, 0, 0, 0]\n", "within +-0.2 rad"),
        ("joint_offset: [0.001, 0.002]\n", "calibration_file has 2 joint offsets"),
    ],
)
def test_bad_arm_calibration_file_is_one_line(run_cli, tmp_path, content, message):
    path = tmp_path / "joint_offsets.yaml"
    if content is not None:
        path.write_text(content)
    flags = ["--set", f"station.arms.rover_arm.calibration_file={path}"]
    code, out, err = run_cli("run", "panel_operation", "--out", tmp_path / "run", *flags)
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and message in err, err


def test_hardware_driver_speaks_the_arm_s_own_joint_angles(tmp_path):
    """On the hardware station a calibration_file's offsets are added to the driver's
    readings and taken from its commands: commanding the arm's reading plus the offsets
    (a standstill in calibrated angles) sends the arm its own reading (no motion), and the
    station reports the reading plus the offsets."""
    from hardware_doubles import RELAXED_SERVO_TIMEOUT, Mz04dScenario

    from guidedarm.diagrams.station.hardware_config import HardwareConfig, NachiDriver
    from guidedarm.systems.hardware.nachi_emulator import NachiEmulator

    offsets = np.array([0.01, -0.01, 0.02, 0.0, 0.0, 0.005])
    path = tmp_path / "joint_offsets.yaml"
    path.write_text("joint_offset: [" + ", ".join(str(v) for v in offsets) + "]\n")
    emulator = NachiEmulator(
        MakeStation(Mz04dScenario()), "mz04d", port=0, servo_timeout=RELAXED_SERVO_TIMEOUT
    )
    thread = threading.Thread(target=emulator.Run, kwargs={"duration": 30.0}, daemon=True)
    thread.start()
    try:
        q0 = emulator.logic.measured.copy()
        driver = NachiDriver(port=emulator.port, acceleration_limits=[20.0] * 6)
        scenario = Mz04dScenario(hardware=HardwareConfig(arms={"mz04d": driver}))
        scenario.arms["mz04d"].calibration_file = str(path)
        station = MakeStation(scenario, kind="hardware")
        simulator = Simulator(station)
        context = simulator.get_mutable_context()
        station.GetInputPort("mz04d.position_commanded").FixValue(context, q0 + offsets)
        simulator.set_target_realtime_rate(1.0)
        simulator.AdvanceTo(0.2)
        measured = station.GetOutputPort("mz04d.position_measured").Eval(context)
        state = station.GetOutputPort("mz04d.state_estimated").Eval(context)
        np.testing.assert_allclose(emulator.logic.commanded, q0, atol=1e-6)
        np.testing.assert_allclose(measured, emulator.logic.measured + offsets, atol=1e-6)
        np.testing.assert_allclose(state[:6], measured)
    finally:
        emulator.Close()
