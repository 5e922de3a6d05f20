"""`guidedarm calibrate camera | hand-eye SCENARIO --hardware`: the photo procedure on a cell
(CellPhotos: the arm moved to each view by its station's position_commanded, a photo and
the measured pose once it rests). No camera emulator exists and the rover arm of the panel
scenario has no driver, so the procedure runs here on the simulated station (the same
code with the station swapped, hardware=False); on hardware only its refusals are tested."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
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
